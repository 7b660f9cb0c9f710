"""Fuzz every codec decode function with arbitrary wire data (hypothesis).

A decode function may reject bad data only with its codec's named error (STYLE.md 9); a
describe function for the bus monitor, a splitter's ``feed`` and a discovery check never
raise at all. Each target runs ``--examples`` generated inputs (100,000 by default); every
other exception is counted per function and one example of each kind is printed.

Last line: ``uncaught: N`` (the number of inputs that raised something else).

    python3 bench/fuzz_codecs.py [--examples N] [--only NAME]
"""

from __future__ import annotations

import argparse
import sys
import time
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from hypothesis import HealthCheck, Phase, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from devices import values as v  # noqa: E402
from devices.electrak import codec as electrak  # noqa: E402
from devices.hdlock import codec as hdlock  # noqa: E402
from devices.m3io import codec as m3io  # noqa: E402
from devices.mo64 import codec as mo64  # noqa: E402
from devices.scu import codec as scu  # noqa: E402

NEVER: tuple[type[BaseException], ...] = ()  # functions that must not raise at all


@dataclass(frozen=True)
class Target:
    """One function under fuzz: ``call(*drawn)`` may raise only ``allowed``."""

    name: str
    strategy: st.SearchStrategy
    call: Callable[..., Any]
    allowed: tuple[type[BaseException], ...]


def _wire(max_size: int = 24) -> st.SearchStrategy[bytes]:
    return st.binary(max_size=max_size)


def _mo64_frame(framing: mo64.Framing) -> st.SearchStrategy[bytes]:
    """Mostly well-sealed frames (so the decoder gets past SD, LE and CRC), some raw noise."""

    def seal(body: bytes) -> bytes:
        raw = bytes((mo64.SD, len(body))) + body
        return raw + mo64.crc16(raw).to_bytes(2, "big")

    return st.one_of(st.binary(max_size=24).map(seal), st.binary(max_size=24))


def _scu_frame() -> st.SearchStrategy[bytes]:
    """Sealed frames starting with a known command (past the CRC and command checks), some raw noise."""

    def seal(parts: tuple[bytes, bytes]) -> bytes:
        body = parts[0] + parts[1]
        return body + scu.crc16(body).to_bytes(2, "little")

    commands = st.sampled_from(sorted(scu.COMMANDS))
    return st.one_of(st.tuples(commands, st.binary(max_size=20)).map(seal), st.binary(max_size=24))


def _scu_sealed_le(body: bytes) -> bytes:
    return body + scu.crc16(body).to_bytes(2, "little")


def _feed(make_splitter):
    """Chunks fed to a new splitter from ``make_splitter()``, then what it still holds expired."""
    def feed(chunks: list[bytes]) -> None:
        splitter = make_splitter()
        for chunk in chunks:
            splitter.feed(chunk)
        splitter.expire()
    return feed


def _mo64_describe(raw: bytes, framing: mo64.Framing, to_device: bool) -> None:
    try:
        frame = mo64.decode_frame(raw, framing)
    except mo64.FrameError:
        return  # decode_frame has its own target; describe takes frames that passed it
    mo64.describe(frame, to_device)


_CAN_ID = st.one_of(st.integers(0, 0x7FF), st.integers(0, 0x1FFFFFFF))
_HD_REQUEST_ID = st.one_of(st.sampled_from(sorted(hdlock.CAN_REQUEST_IDS)), _CAN_ID)
_ELECTRAK_ID = st.one_of(st.sampled_from(sorted({electrak.CONTROL_ID, electrak.STATUS_ID, electrak.SERVICE_REQUEST_ID,
                                                 electrak.SERVICE_RESPONSE_ID, *electrak.INTERNAL_IDS})), _CAN_ID)
_M3IO_IDS = m3io.derive_ids(0)
_M3IO_ID = st.one_of(st.sampled_from(sorted(_M3IO_IDS.by_name().values())), _CAN_ID)
_VARIANT = st.sampled_from(list(m3io.Variant))
_MO64_FRAMING = st.sampled_from([mo64.TCP, mo64.RS485])
_CHUNKS = st.lists(st.binary(max_size=40), max_size=6)

TARGETS: list[Target] = [
    # Electrak HD (CAN)
    Target("electrak.ControlFrame.decode", _wire(), electrak.ControlFrame.decode, (electrak.CodecError,)),
    Target("electrak.StatusFrame.decode", _wire(), electrak.StatusFrame.decode, (electrak.CodecError,)),
    Target("electrak.ServiceMessage.decode", _wire(), electrak.ServiceMessage.decode, (electrak.CodecError,)),
    Target("electrak.describe_frame", st.tuples(_ELECTRAK_ID, st.booleans(), _wire(12)),
           lambda a: electrak.describe_frame(a[0], a[1], a[2], {(False, electrak.STATUS_ID)}), NEVER),
    # HD-Lock (CAN)
    Target("hdlock.decode_request", st.tuples(_HD_REQUEST_ID, _wire(16), st.booleans()),
           lambda a: hdlock.decode_request(hdlock.CanFrame(a[0], a[1], a[2])), (hdlock.CodecError,)),
    Target("hdlock.decode_lock_frame", _wire(16), hdlock.decode_lock_frame, (hdlock.CodecError,)),
    Target("hdlock.describe_frame", st.tuples(_HD_REQUEST_ID, st.booleans(), _wire(16)),
           lambda a: hdlock.describe_frame(a[0], a[1], a[2], {(a[1], a[0])}), NEVER),
    Target("hdlock.discovered", st.tuples(_CAN_ID, st.booleans(), st.one_of(_wire(16), _wire(6).map(lambda b: b"\0\0" + b))),
           lambda a: hdlock.discovered(a[0], a[1], a[2]), NEVER),
    # CAN-M3IO
    Target("m3io.decode_dig_out", st.tuples(_VARIANT, _wire(4)), lambda a: m3io.decode_dig_out(*a), (m3io.CodecError,)),
    Target("m3io.decode_dig_in", _wire(4), m3io.decode_dig_in, (m3io.CodecError,)),
    Target("m3io.decode_temps", st.tuples(_wire(12), st.sampled_from([2, 4])), lambda a: m3io.decode_temps(*a),
           (m3io.CodecError,)),
    Target("m3io.decode_u16", _wire(8), m3io.decode_u16, (m3io.CodecError,)),
    Target("m3io.MData.decode", _wire(12), m3io.MData.decode, (m3io.CodecError,)),
    Target("m3io.decode_serial", _wire(8), m3io.decode_serial, (m3io.CodecError,)),
    Target("m3io.describe_frame_for", st.tuples(st.integers(0, 0xFF), _VARIANT, _M3IO_ID, _wire(10)),
           lambda a: m3io.describe_frame_for(m3io.derive_ids(a[0]), a[1], a[2], a[3]), NEVER),
    # MO 64 (LogiTed)
    Target("mo64.decode_frame", st.tuples(st.one_of(_mo64_frame(mo64.TCP), _wire(30)), _MO64_FRAMING),
           lambda a: mo64.decode_frame(*a), (mo64.FrameError,)),
    Target("mo64.decode_answer", st.tuples(_mo64_frame(mo64.TCP), _MO64_FRAMING),
           lambda a: mo64.decode_answer(*a), (mo64.CodecError,)),
    Target("mo64.decode_request", st.tuples(_mo64_frame(mo64.TCP), _MO64_FRAMING),
           lambda a: mo64.decode_request(*a), (mo64.CodecError,)),
    Target("mo64.decode_value", st.tuples(st.integers(0, 0x25), _wire(40)), lambda a: mo64.decode_value(*a),
           (mo64.CodecError, v.DecodeError)),  # docstring: DecodeError for short/excess data, CodecError for a non-answer
    Target("mo64.describe", st.tuples(_mo64_frame(mo64.TCP), _MO64_FRAMING, st.booleans()),
           lambda a: _mo64_describe(*a), NEVER),
    Target("mo64.FrameSplitter.feed(tcp)", _CHUNKS, _feed(lambda: mo64.FrameSplitter(mo64.TCP)), NEVER),
    Target("mo64.FrameSplitter.feed(rs485)", _CHUNKS, _feed(lambda: mo64.FrameSplitter(mo64.RS485)), NEVER),
    # Ewellix SCU (serial)
    Target("scu.decode_answer", st.tuples(_scu_frame(), st.one_of(st.none(), st.sampled_from(sorted(scu.COMMANDS)))),
           lambda a: scu.decode_answer(*a), (scu.CodecError,)),
    Target("scu.decode_request", _scu_frame(), scu.decode_request, (scu.CodecError,)),
    Target("scu.FrameSplitter.feed(answers)", _CHUNKS, _feed(lambda: scu.FrameSplitter(scu.ANSWERS)), NEVER),
    Target("scu.FrameSplitter.feed(requests)", _CHUNKS, _feed(lambda: scu.FrameSplitter(scu.REQUESTS)), NEVER),
]


def uncaught(target: Target, examples: int) -> tuple[Counter, dict[str, Any]]:
    """Run ``examples`` inputs; count exceptions other than ``target.allowed`` by type and first line."""
    seen: Counter = Counter()
    sample: dict[str, Any] = {}

    @settings(max_examples=examples, deadline=None, database=None, derandomize=False,
              phases=(Phase.generate,), suppress_health_check=list(HealthCheck))
    @given(target.strategy)
    def run(drawn):
        try:
            target.call(drawn)
        except target.allowed:
            pass
        except Exception as exc:  # noqa: BLE001 - the point: anything else is a finding
            key = f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}"[:120]
            seen[key] += 1
            sample.setdefault(key, drawn)

    run()
    return seen, sample


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--examples", type=int, default=100_000, help="inputs per function (default 100,000)")
    parser.add_argument("--only", default="", help="run only targets whose name contains this")
    args = parser.parse_args(argv)
    total = 0
    for target in TARGETS:
        if args.only and args.only not in target.name:
            continue
        start = time.perf_counter()
        seen, sample = uncaught(target, args.examples)
        n = sum(seen.values())
        total += n
        print(f"{target.name:36s} {args.examples:>8,} examples {time.perf_counter() - start:6.1f} s  uncaught {n}",
              flush=True)
        for key, count in seen.most_common():
            print(f"    {count:>7,} x {key}  e.g. {sample[key]!r}"[:300], flush=True)
    print(f"uncaught: {total}")
    return 1 if total else 0


if __name__ == "__main__":
    sys.exit(main())
