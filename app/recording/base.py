"""What every part of the recordings shares: the file formats python-can writes and reads, the
limits, and the one error."""

from __future__ import annotations

import can
from can.io.asc import ASCReader, ASCWriter
from can.io.blf import BLFReader, BLFWriter
from can.io.canutils import CanutilsLogReader, CanutilsLogWriter
from can.io.csv import CSVReader, CSVWriter
from can.io.trc import TRCReader, TRCWriter

from devices.errors import CommissionError

# suffix -> (writer class, what the engineer sees in the format select)
WRITERS: dict[str, tuple[type[can.io.generic.MessageWriter], str]] = {
    ".log": (CanutilsLogWriter, "candump .log"),
    ".asc": (ASCWriter, "Vector .asc"),
    ".blf": (BLFWriter, "Vector .blf"),
    ".csv": (CSVWriter, "python-can .csv"),
    ".trc": (TRCWriter, "PEAK .trc"),
}
READERS: dict[str, type[can.io.generic.MessageReader]] = {
    ".log": CanutilsLogReader, ".asc": ASCReader, ".blf": BLFReader, ".csv": CSVReader, ".trc": TRCReader,
}
READ_SUFFIXES = tuple(READERS)  # what python-can reads without extras
SNIFF_BYTES = 4096  # the head of a file looked at to tell its format
PROGRESS_FRAMES = 5_000  # frames between two progress reports while reading a file
MAX_FILE_FRAMES = 200_000  # frames kept of an opened file (memory bound)
MAX_CACHE = 20_000  # decoded texts kept per decoder
DIR_ENV = "COMMISSION_RECORDINGS_DIR"
UNKNOWN = "unknown"

Key = tuple[bool, int]


class RecordingError(CommissionError):
    """A recording that cannot be started, or a file that cannot be read; the message says why."""
