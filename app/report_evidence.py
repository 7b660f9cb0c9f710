"""The evidence files of the as-left archive: each checkout step's bus traffic in a standard format (CAN frames
as a candump ``.log`` and a PEAK ``.trc`` by python-can; serial, Modbus and LogiTed transactions as text, times in
UTC), named and hashed once per step of a stored run."""

from __future__ import annotations

import tempfile
from datetime import datetime, timezone
from pathlib import Path

from app.i18n import N_
from app.verify import sha256


def evidence_file(device: str, bus: str, run_id: int, n: int, evidence: dict) -> tuple[str, bytes] | None:
    """The evidence file of step ``n`` of checkout ``run_id`` (its name in the archive and its bytes):
    CAN frames as a candump log, serial, Modbus and LogiTed transactions as text; None without traffic."""
    stem = f"evidence/{device}/checkout-{run_id}-step{n}"
    if evidence.get("kind") == "can" and evidence.get("frames"):
        return f"{stem}.log", can_trace(evidence["frames"], ".log", bus)
    if evidence.get("transactions"):
        return f"{stem}.txt", serial_trace(evidence["transactions"])
    return None


_EVIDENCE_NAMED: dict[tuple, dict | None] = {}  # (row hash, step) -> name and SHA-256: record rows never change
EVIDENCE_NAMED_MAX = 4096


def evidence_named(row: str | None, device: str, bus: str, run_id: int, n: int, evidence: dict) -> dict | None:
    """The evidence file of a step as the report names it (file name, SHA-256, how many items); made
    once per step of a stored run (``row``: its hash; the record page's preview asks every few seconds)."""
    key = (row, device, bus, run_id, n)
    if row is None or key not in _EVIDENCE_NAMED:
        made = evidence_file(device, bus, run_id, n, evidence)
        if len(_EVIDENCE_NAMED) >= EVIDENCE_NAMED_MAX:
            _EVIDENCE_NAMED.pop(next(iter(_EVIDENCE_NAMED)))
        _EVIDENCE_NAMED[key] = None if made is None else {
            "name": made[0], "sha256": sha256(made[1]), "items": len(evidence.get("frames") or evidence.get("transactions") or []),
            "what": N_("CAN frames") if evidence.get("kind") == "can" else N_("transactions")}
    return _EVIDENCE_NAMED[key]


def can_trace(frames: list[dict], suffix: str, channel: str) -> bytes:
    """CAN frames of a step in a standard format: ``.log`` (candump) or ``.trc`` (PEAK), by python-can."""
    import can

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / f"trace{suffix}"
        writer = can.CanutilsLogWriter(path, channel=channel) if suffix == ".log" else can.TRCWriter(path, channel=1)
        with writer:
            for f in frames:
                writer.on_message_received(can.Message(timestamp=f["t"], arbitration_id=f["id"], is_extended_id=f["ext"],
                                                       data=bytes.fromhex(f["data"]), is_rx=f["dir"] == "rx",
                                                       is_error_frame=f.get("err", False), channel=channel))
        return path.read_bytes()


def serial_trace(rows: list[dict]) -> bytes:
    """Serial, Modbus and LogiTed transactions as text, one a line, times in UTC (the same bytes wherever made)."""
    def utc(t: float) -> str:
        return datetime.fromtimestamp(t, timezone.utc).strftime("%Y-%m-%dT%H:%M:%S.%f")[:-3] + "Z"

    return "".join(f"{utc(r['t'])} TX {r['tx']} RX {r['rx']} {r['decoded']} {r['error']}\n" for r in rows).encode()
