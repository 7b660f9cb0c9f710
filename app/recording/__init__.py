"""CAN bus recordings and the pure helpers of the bus monitor.

A recording is a python-can writer (candump ``.log``, Vector ``.asc``, ``.blf``,
``.csv``, PEAK ``.trc``) attached to :attr:`app.can_bus.CanBusState.recorder`; the bus feeds it every
frame it records (received and sent). Starting and stopping happen in the event loop,
the same thread that feeds the writer, so no frame reaches a closed file. Recorded files
are read back with python-can's readers into :class:`~app.can_bus.FrameRecord` rows; the
format is taken from the file's content (:func:`detect_format`), the suffix only when the
content does not tell, and a file that cannot be read names the line (text formats) or
byte offset (BLF) where reading stopped. Recordings live in the data folder, beside the
backups and the audit log (:func:`recordings_dir`).

Decoding and filtering are plain functions of ``(arbitration_id, is_extended, data)``
that ask the device codecs (``describe_frame``) and the device adapters
(``owns_frame``), which also name the device that sent or answered a frame. Modbus
transactions are decoded through the parameter model of the device at their unit
(:class:`TransactionDecoder`). No UI here.

The package is split along those concerns: :mod:`.write`, :mod:`.read`, :mod:`.decode`,
:mod:`.filters` and :mod:`.modbus`, over :mod:`.base`; every public name is also here, as before
(each module's private helpers stay in it).
"""

from __future__ import annotations

from app.recording.base import (  # noqa: F401
    DIR_ENV,
    Key,
    MAX_CACHE,
    MAX_FILE_FRAMES,
    PROGRESS_FRAMES,
    READERS,
    READ_SUFFIXES,
    RecordingError,
    SNIFF_BYTES,
    UNKNOWN,
    WRITERS,
)
from app.recording.write import (  # noqa: F401
    RECORDINGS_SUBDIR,
    RECORD_QUEUE,
    Recording,
    RecordingFile,
    UPLOADS_KEPT,
    UPLOADS_SUBDIR,
    active_recording,
    list_recordings,
    recording_path,
    recordings_dir,
    start_recording,
    stop_recording,
    store_upload,
    upload_name,
)
from app.recording.read import (  # noqa: F401
    LoadedLog,
    Progress,
    detect_format,
    file_format,
    iter_log,
    load_log,
    read_log,
)
from app.recording.decode import (  # noqa: F401
    AdapterDescriber,
    FrameDecoder,
    can_codecs,
    describe,
    describers,
    ids_of_devices,
)
from app.recording.filters import (  # noqa: F401
    FrameFilter,
    MAX_DEVICE_NAMES,
    Owner,
    changed_bytes,
    device_of,
    device_owners,
    format_data,
    format_id,
    format_time,
    newest,
    owner_of,
    parse_id,
)
from app.recording.modbus import (  # noqa: F401
    MAX_DECODED_REGISTERS,
    TransactionDecoder,
    describe_registers,
)
