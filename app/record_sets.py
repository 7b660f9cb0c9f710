"""Parameter sets of the commissioning record: a backup's list as a set, two sets compared, the live
values against the approved set, and drift (the approved settings that differ now).

Plain functions of dictionaries and a device's live record (``DeviceState``): no storage, no I/O.
The record service (app/record.py) keeps each device's drift up to date with them; the report
(app/report.py) compares with them.
"""

from __future__ import annotations

from typing import Any


def param_set(entries: list[dict]) -> dict[str, dict]:
    """A backup's parameter list as ``{key: {name, raw, text, unit, writable}}``."""
    return {e["key"]: {"name": e.get("name", e["key"]), "raw": e.get("raw"), "text": str(e.get("text") or e.get("value")),
                       "unit": e.get("unit", ""), "writable": bool(e.get("writable"))} for e in entries}


def diff_sets(old: dict[str, dict], new: dict[str, dict]) -> list[dict]:
    """Rows of every parameter that differs (or exists in only one set), in the order of ``new``."""
    rows = []
    for key in [*new, *(k for k in old if k not in new)]:
        a, b = old.get(key), new.get(key)
        if a is not None and b is not None and a.get("raw") == b.get("raw"):
            continue
        ref = b or a
        rows.append({"key": key, "name": ref["name"], "old": None if a is None else a["text"],
                     "new": None if b is None else b["text"]})
    return rows


LIVE_VALUE = "live value"  # a read-only value (state, measurement, counter) that differs: not a setting, never "changed"


def compare_with_approved(current: dict[str, dict], approved: dict[str, dict] | None) -> list[dict]:
    """Every current parameter against the approved set: ``equal``, ``changed`` or ``not approved``;
    a differing value the device changes itself is ``updated by the device``, and a differing read-only
    value (the bolt's position, a state, a timer: read with the set, but no setting) a ``live value``,
    as drift leaves both out."""
    rows = []
    for key, now in current.items():
        ref = None if approved is None else approved.get(key)
        if ref is None:
            verdict = "not approved"
        elif _same(ref.get("raw"), now.get("raw")):
            verdict = "equal"
        elif now.get("device_updates"):
            verdict = "updated by the device"
        elif not (now.get("writable") if "writable" in now else ref.get("writable")):
            verdict = LIVE_VALUE
        else:
            verdict = "changed"
        rows.append({"key": key, "name": now["name"], "value": now["text"], "unit": now.get("unit", ""),
                     "approved": None if ref is None else ref["text"], "verdict": verdict, "writable": now.get("writable")})
    return rows


def live_set(state, approved: dict[str, dict]) -> dict[str, dict]:
    """The values of the approved keys as the live store holds them now (the last full read):
    register parameters through the parameter model, other entries by their name's live point."""
    current: dict[str, dict] = {}
    params = state.params
    for key, ref in approved.items():
        param = params.by_key.get(key) if params is not None else None
        if param is not None:
            raw = state.raw(param)
            if raw is not None:
                current[key] = {"name": ref["name"], "raw": raw, "text": param.display(raw), "unit": param.unit}
        else:
            point = state.points.get(ref["name"])
            if point is not None and point.value is not None:
                current[key] = {"name": ref["name"], "raw": point.value, "text": str(point.text or point.value), "unit": point.unit}
    return current


def live_params(state) -> dict[str, dict]:
    """Every register parameter the live store holds now (the device's last poll, as its page shows
    it), in the form of :func:`param_set`; empty for a device without a parameter model or before
    its first read."""
    params = state.params
    current: dict[str, dict] = {}
    for param in params if params is not None else ():
        raw = state.raw(param)
        if raw is not None:
            current[param.key] = {"name": param.label or param.name, "raw": raw, "text": param.display(raw), "unit": param.unit,
                                  "writable": bool(param.writable)}
    return current


def device_updated(state, key: str) -> bool:
    """The parameter model marks ``key`` as changed by the device itself (``Param.device_updates``:
    a measured maximum, a counter): never drift."""
    params = state.params
    param = params.by_key.get(key) if params is not None else None
    return param is not None and param.writable and not param.setting


def drift_of(state, approved: dict[str, dict], snapshot: dict[str, dict] | None = None) -> list[dict]:
    """The writable approved parameters whose value now differs (live store first, else the last
    snapshot); parameters the device changes itself are left out."""
    current = dict(snapshot or {})
    current.update(live_set(state, approved))
    rows = []
    for key, ref in approved.items():
        now = current.get(key)
        if not ref.get("writable") or now is None or _same(now.get("raw"), ref.get("raw")) or device_updated(state, key):
            continue
        rows.append({"key": key, "name": ref["name"], "approved": ref["text"], "now": now["text"]})
    return rows


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, int | float) and isinstance(b, int | float):
        return a == b
    return str(a) == str(b)
