"""MCAP files (the ``mcap`` package) of a CAN recording or of the session's live data, for Foxglove and PlotJuggler.

Channels, every message JSON with a JSON schema (``jsonschema`` encoding, which both open):

- ``/can/<bus>``: one message per CAN frame: ``id``, ``extended``, ``dlc``, ``data`` (bytes as a list of
  numbers, and as hex text), ``direction``, ``error``, the frame decoded in words (``decoded``) and the
  device that sent or answered it, as the bus monitor decodes them (app/recording.py);
- ``/points/<device>``: the device's chart samples (numbers by point name) from the state store's history,
  then the current value of every live point (numbers and booleans as numbers, the rest as text) -
  what PlotJuggler plots as one series per field.

Log and publish times are the frames' and the samples' own times in nanoseconds since the epoch.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from mcap.writer import CompressionType, Writer

from app import cli_lang
from app.cli_lang import _
from app.message import said

FRAME_SCHEMA = {
    "title": "commission.CanFrame", "type": "object",
    "properties": {
        "timestamp": {"type": "object", "properties": {"sec": {"type": "integer"}, "nsec": {"type": "integer"}}},
        "bus": {"type": "string"}, "id": {"type": "integer"}, "extended": {"type": "boolean"},
        "dlc": {"type": "integer"}, "data": {"type": "array", "items": {"type": "integer"}}, "hex": {"type": "string"},
        "direction": {"type": "string"}, "error": {"type": "boolean"}, "remote": {"type": "boolean"},
        "device": {"type": "string"}, "decoded": {"type": "string"},
    },
}
POINTS_SCHEMA = {
    "title": "commission.DevicePoints", "type": "object",
    "properties": {"timestamp": {"type": "object", "properties": {"sec": {"type": "integer"}, "nsec": {"type": "integer"}}},
                   "device": {"type": "string"}, "values": {"type": "object", "additionalProperties": {"type": ["number", "string", "null"]}},
                   "units": {"type": "object", "additionalProperties": {"type": "string"}},
                   "quality": {"type": "object", "additionalProperties": {"type": "string"}}},
}


def _ns(t: float) -> int:
    return int(round(t * 1e9))


def _stamp(t: float) -> dict[str, int]:
    ns = _ns(t)
    return {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000}


def _plottable(value: Any) -> Any:
    if isinstance(value, bool):
        return int(value)
    if isinstance(value, int | float):
        return value if math.isfinite(value) else None
    if value is None:
        return None
    return value if isinstance(value, str) else json.dumps(value, default=str, sort_keys=True)


class McapFile:
    """One MCAP file being written: a channel per CAN bus and per device, registered when first used."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        self._out = self.path.open("wb")
        self.writer = Writer(self._out, compression=CompressionType.ZSTD)
        self.writer.start(profile="", library="commission")
        self._frame_schema = self.writer.register_schema("commission.CanFrame", "jsonschema", json.dumps(FRAME_SCHEMA).encode())
        self._points_schema = self.writer.register_schema("commission.DevicePoints", "jsonschema", json.dumps(POINTS_SCHEMA).encode())
        self._channels: dict[str, int] = {}
        self._sequence: dict[int, int] = {}
        self.messages = 0

    def _channel(self, topic: str, schema: int) -> int:
        channel = self._channels.get(topic)
        if channel is None:
            channel = self._channels[topic] = self.writer.register_channel(topic, "json", schema)
            self._sequence[channel] = 0
        return channel

    def _add(self, channel: int, t: float, message: dict[str, Any]) -> None:
        self._sequence[channel] += 1
        ns = _ns(t)
        self.writer.add_message(channel, log_time=ns, publish_time=ns, sequence=self._sequence[channel],
                                data=json.dumps(message, separators=(",", ":"), allow_nan=False).encode())
        self.messages += 1

    def frame(self, bus: str, rec, device: str = "", decoded: str = "") -> None:
        """One CAN frame (an :class:`app.can_bus.FrameRecord`)."""
        data = bytes(rec.data)
        self._add(self._channel(f"/can/{bus}", self._frame_schema), rec.time, {
            "timestamp": _stamp(rec.time), "bus": bus, "id": rec.arbitration_id, "extended": bool(rec.is_extended_id),
            "dlc": rec.dlc, "data": list(data), "hex": data.hex(" "), "direction": rec.direction,
            "error": bool(rec.is_error_frame), "remote": bool(rec.is_remote_frame),
            "device": device, "decoded": decoded})

    def points(self, device: str, t: float, values: dict[str, Any], units: dict[str, str] | None = None,
               quality: dict[str, str] | None = None) -> None:
        message = {"timestamp": _stamp(t), "device": device, "values": {k: _plottable(v) for k, v in values.items()}}
        if units:
            message["units"] = units
        if quality:
            message["quality"] = quality
        self._add(self._channel(f"/points/{device}", self._points_schema), t, message)

    def close(self) -> None:
        self.writer.finish()
        self._out.close()

    def __enter__(self) -> McapFile:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def export_recording(source: str | Path, out: str | Path, bus: str | None = None, codecs: Iterable | None = None) -> int:
    """A recorded CAN file (any format app/recording.py reads) as MCAP, each frame decoded in words by the
    device codecs; returns the number of messages. Blocking: run it off the loop."""
    from app.recording import FrameDecoder, can_codecs, ids_of_devices, iter_log

    source = Path(source)
    bus = bus or source.stem
    chunks = list(iter_log(source))
    frames = [rec for chunk in chunks for rec in chunk]
    codec_list = list(codecs) if codecs is not None else can_codecs()
    decoder = FrameDecoder(ids_of_devices(frames, codec_list), codec_list)
    with McapFile(out) as mcap_file:
        for rec in frames:
            text = "" if rec.is_error_frame else decoder.record(rec)
            mcap_file.frame(bus, rec, decoded=text)
        return mcap_file.messages


def export_live(runtime, out: str | Path) -> int:
    """The session's live data as MCAP: the frames in every CAN bus's monitor buffer (decoded as the
    monitor shows them), every device's chart history and the current value of each live point.
    Blocking; from the event loop use :func:`collect_live` there and :func:`write_live` in a thread."""
    return write_live(collect_live(runtime), out)


def collect_live(runtime) -> list[tuple[float, int, tuple]]:
    """A copy of what :func:`write_live` writes, taken at once (on the loop that changes it)."""
    from app.recording import FrameDecoder, can_codecs, device_owners

    rows: list[tuple[float, int, tuple]] = []
    for name, can_bus in runtime.worker.can_buses.items():
        decoder = FrameDecoder(runtime.worker.known_ids(name), can_codecs())
        decoder.set_owners(device_owners(runtime.worker, name))
        for rec in list(can_bus.state.frames):
            decoded = "" if rec.is_error_frame else decoder.record(rec)
            rows.append((rec.time, 0, ("frame", name, rec, decoder.record_device(rec), decoded)))
    for name, state in list(runtime.store.devices.items()):
        for t, sample in list(state.history):
            rows.append((t, 1, ("points", name, t, dict(sample), None, None)))
        values = state.values()
        if values:
            t = max((e["time"] for e in values.values() if isinstance(e.get("time"), int | float)), default=time.time())
            rows.append((t, 2, ("points", name, t, {k: e.get("value") for k, e in values.items()},
                                {k: e.get("unit") or "" for k, e in values.items()},
                                {k: e.get("quality") or "" for k, e in values.items()})))
    rows.sort(key=lambda row: (row[0], row[1]))  # MCAP readers like log times in order
    return rows


def write_live(rows: list[tuple[float, int, tuple]], out: str | Path) -> int:
    with McapFile(out) as mcap_file:
        for _t, _order, item in rows:
            if item[0] == "frame":
                mcap_file.frame(item[1], item[2], device=item[3], decoded=item[4])
            else:
                mcap_file.points(item[1], item[2], item[3], item[4], item[5])
        return mcap_file.messages


# -- commission export --format mcap ---------------------------------------------------------------------
def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    parser = subparsers.add_parser("export", help=_("export a CAN recording, or a while of the plant's live data, as MCAP "
                                   "(Foxglove, PlotJuggler)"))
    parser.add_argument("--format", choices=["mcap"], default="mcap", help=_("file format (mcap)"))
    parser.add_argument("recording", type=Path, nargs="?", help=_("a recorded CAN file (.log, .asc, .blf, .csv, .trc)"))
    parser.add_argument("--bus", default=None, help=_("bus name for the recording's channel (default: the file's name)"))
    parser.add_argument("--live", type=float, default=None, metavar="SECONDS",
                        help=_("instead of a recording: run the plant this long and export its live data"))
    parser.add_argument("--plant", type=Path, default=None, help=_("with --live: plant file (default: the built-in demo plant)"))
    parser.add_argument("--no-sim", action="store_true", help=_("with --live: do not start simulated devices"))
    parser.add_argument("--out", type=Path, required=True, help=_("the .mcap file to write"))
    parser.set_defaults(func=run)
    return parser


def run(args: argparse.Namespace) -> int:
    import sys

    if (args.recording is None) == (args.live is None):
        print(_("commission export: give a recording file or --live SECONDS (one of them)"), file=sys.stderr)
        return 2
    unwritable = _unwritable(Path(args.out))  # said before a recording is read or the plant runs for --live
    if unwritable:
        print(_("commission export: cannot write {path}: {reason}").format(path=args.out, reason=unwritable), file=sys.stderr)
        return 2
    try:
        return _export(args)
    except OSError as exc:  # the disk filled up meanwhile, the folder went away ...
        print(_("commission export: cannot write {path}: {reason}").format(path=args.out, reason=exc.strerror or exc),
              file=sys.stderr)
        return 1


def _unwritable(out: Path) -> str:
    """Why the export cannot be written to ``out`` ("" when it can, as far as can be told before writing)."""
    import os

    folder = out.parent  # "." for a bare file name
    if out.is_dir():
        return _("it is a folder; name a file, e.g. {example}").format(example=out / "export.mcap")
    if not folder.is_dir():
        return _("the folder {folder} does not exist").format(folder=folder)
    if not os.access(folder, os.W_OK) or (out.exists() and not os.access(out, os.W_OK)):
        return _("no permission to write there")
    return ""


def _export(args: argparse.Namespace) -> int:
    import sys

    if args.recording is not None:
        from app.recording import RecordingError

        try:
            count = export_recording(args.recording, args.out, bus=args.bus)
        except RecordingError as exc:  # a file it cannot read, said in the command line's language (where it stopped)
            print(f"commission export: {said(exc, cli_lang.lang())}", file=sys.stderr)
            return 1
        print(_("{path}: {count} messages from {recording}").format(path=args.out, count=count, recording=args.recording))
        return 0
    import asyncio

    from app.headless import load_plant_or_exit
    from app.runtime import Runtime

    plant = load_plant_or_exit(args.plant)

    async def session() -> int:
        runtime = Runtime(plant, simulate=not args.no_sim)
        await runtime.start()
        try:
            await asyncio.sleep(args.live)
            return await asyncio.to_thread(write_live, collect_live(runtime), args.out)
        finally:
            await runtime.stop()

    count = asyncio.run(session())
    print(_("{path}: {count} messages of {seconds} s of plant {plant}").format(path=args.out, count=count, seconds=f"{args.live:g}",
                                                                              plant=plant.name))
    return 0
