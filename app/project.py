"""The offline project: each device's intended parameters, named in the plant file.

A ``[[device]]`` table may carry ``project``, either a table of parameter = value (by the name the
device's parameter table shows, e.g. ``LockRequestDelay = 300``; inline or as ``[device.project]``)
or the name of a parameter file in the backup format (relative to the plant file)::

    [[device]]
    name = "door-1"
    ...
    project = { LockRequestDelay = 300, LockDelay = 50 }

    [[device]]
    name = "door-2"
    ...
    project = "projects/door-2.json"

Every entry is checked by the device type's parameter model without the device (a known name,
writable, in range, a whole number where the register holds one, an enum value);
``commission check --plant P`` lists invalid and unknown entries with file:line. Against a device,
the project is a backup document (:func:`document`), so the backup page shows it with restore's
diff and applies a row through restore's verified write; "update the project" rewrites one entry
of the plant file or the parameter file atomically (:func:`update_entry`).
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from app import backup
from app.plant import Plant, PlantError, load_plant, parse_plant
from devices.params import Param, ParamError
from devices.registry import DEVICE_TYPES


class ProjectError(ValueError):
    """A project that cannot be read or changed; the message names file and line."""


@dataclass
class ProjectEntry:
    device: str
    name: str  # as the project names it
    value: Any
    file: str
    line: int
    key: str = ""  # the parameter's key when the model knows it
    raw: int | None = None  # what would be written, when valid
    error: str = ""
    param: Param | None = None

    @property
    def where(self) -> str:
        return f"{self.file}:{self.line}"


def _lookup(params, name: str) -> Param | None:
    if params is None:
        return None
    if name in params.by_name:
        return params.by_name[name]
    if name in params.by_key:
        return params.by_key[name]
    return next((p for p in params if p.name == name), None)


def _device_span(lines: list[str], start: int) -> range:
    """The 0-based lines of the ``[[device]]`` table whose header is on line ``start`` (1-based), with its sub-tables."""
    end = len(lines)
    for i in range(start, len(lines)):
        if re.match(r"^\s*\[\[", lines[i]):
            end = i
            break
    return range(start - 1, end)


def _name_pattern(name: str) -> re.Pattern:
    quoted = re.escape(json.dumps(name))
    bare = re.escape(name)
    return re.compile(rf"(^|[{{,\s])((?:{quoted}|{bare})\s*=\s*)")


def _entry_line(text: str, start: int, name: str) -> int:
    lines = text.splitlines()
    pattern = _name_pattern(name)
    span = _device_span(lines, start)
    seen_project = False
    for i in span:
        if re.match(r"^\s*(project\s*=|\[\s*device\s*\.\s*project\s*\])", lines[i]):
            seen_project = True
        if seen_project and pattern.search(lines[i]):
            return i + 1
    return start


def _check(params, device: str, name: str, value: Any) -> tuple[Param | None, int | None, str]:
    if params is None:
        return None, None, "this device type has no parameter model: its project cannot be checked or applied"
    param = _lookup(params, name)
    if param is None:
        close = [p for p in params.by_name if p.lower().startswith(name.lower()[:6])][:3]
        hint = f"; did you mean {', '.join(close)}?" if close else ""
        return None, None, f"unknown parameter {name!r}{hint}"
    if isinstance(value, bool) or not isinstance(value, int | float | str):
        return param, None, f"{name}: {value!r} is not a number or an enum name"
    try:
        raw = param.validate(value)
    except ParamError as exc:
        return param, None, str(exc)
    return param, raw, ""


def project_file(plant: Plant, device: str) -> Path | None:
    config = plant.devices[device]
    if not isinstance(config.project, str):
        return None
    path = Path(config.project)
    if not path.is_absolute() and plant.path is not None:
        path = plant.path.parent / path
    return path


def entries(plant: Plant, device: str) -> list[ProjectEntry]:
    """The device's project entries, each checked by the parameter model (``error`` names what is wrong)."""
    config = plant.devices[device]
    params = DEVICE_TYPES[config.type].params
    where = str(plant.path) if plant.path else "<plant>"
    found: list[ProjectEntry] = []
    if config.project is None:
        return found
    if isinstance(config.project, dict):
        text = plant.path.read_text(encoding="utf-8") if plant.path and plant.path.exists() else ""
        for name, value in config.project.items():
            entry = ProjectEntry(device, name, value, where, _entry_line(text, config.line, name) if text else config.line)
            entry.param, entry.raw, entry.error = _check(params, device, name, value)
            entry.key = entry.param.key if entry.param is not None else ""
            found.append(entry)
        return found
    path = project_file(plant, device)
    try:
        text = path.read_text(encoding="utf-8")
        document = backup.load_document(text, str(path))
    except OSError as exc:
        return [ProjectEntry(device, "", None, where, config.line, error=f"project file {path}: {exc.strerror or exc}")]
    except backup.BackupError as exc:
        return [ProjectEntry(device, "", None, str(path), 1, error=str(exc))]
    doc_type = document["device"].get("type")
    if doc_type != config.type:
        return [ProjectEntry(device, "", None, str(path), 1,
                             error=f"the parameter file is of a {doc_type!r}, device '{device}' is a {config.type!r}")]
    lines = text.splitlines()
    for item in document["parameters"]:
        if not item.get("writable"):
            continue  # read-only entries are kept for reference, never written
        key = item["key"]
        line = next((i + 1 for i, t in enumerate(lines) if f'"{key}"' in t), 1)
        entry = ProjectEntry(device, item["name"], item.get("value"), str(path), line)
        param = params.by_key.get(key) if params is not None else None
        if param is None and params is not None:
            entry.error = f"unknown parameter {item['name']!r} ({key})"
        else:
            entry.param, entry.raw, entry.error = _check(params, device, param.label or param.name if param else item["name"],
                                                         item.get("value"))
            if not entry.error and "raw" in item and item["raw"] != entry.raw:
                entry.error = f"{item['name']}: raw {item['raw']!r} and value {item.get('value')!r} disagree"
        entry.key = entry.param.key if entry.param is not None else key
        found.append(entry)
    return found


def check_plant(plant: Plant) -> list[str]:
    """Every invalid or unknown project entry of the plant, as ``file:line: device 'x': problem``."""
    problems = []
    for name in plant.devices:
        for entry in entries(plant, name):
            if entry.error:
                problems.append(f"{entry.where}: device '{name}': {entry.error}")
    return problems


def has_project(plant: Plant, device: str) -> bool:
    config = plant.devices.get(device)
    return config is not None and config.project is not None


def document(runtime, device: str) -> dict:
    """The device's project as a backup document: every entry, valid or not (an invalid one shows in
    restore's diff as "not written" with the reason)."""
    plant = runtime.plant
    if not has_project(plant, device):
        raise backup.BackupError(f"{device}: the plant file names no project for it")
    state = runtime.store.devices[device]
    items = []
    for entry in entries(plant, device):
        if not entry.key:
            continue
        item = {"key": entry.key, "name": entry.param.label or entry.param.name if entry.param else entry.name,
                "value": entry.value, "writable": True}
        if entry.param is not None and entry.raw is not None:
            item.update(raw=entry.raw, unit=entry.param.unit, text=entry.param.display(entry.raw))
        elif entry.param is not None:
            item.update(unit=entry.param.unit)
        items.append(item)
    doc = backup.make_document(plant.name, device, state.type, state.bus, {}, items)
    doc["source"] = "project"
    return doc


def _toml_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return repr(value)
    return json.dumps(str(value))


def update_entry(plant: Plant, device: str, key: str, value: Any) -> ProjectEntry:
    """Set the project's entry for ``key`` to ``value`` (checked by the parameter model first) and
    rewrite the plant file or the parameter file atomically; the running plant follows."""
    config = plant.devices[device]
    params = DEVICE_TYPES[config.type].params
    param = params.by_key.get(key) if params is not None else None
    if param is None:
        raise ProjectError(f"{key!r} is not a parameter of {device}")
    try:
        raw = param.validate(value)
    except ParamError as exc:
        raise ProjectError(str(exc)) from None
    if isinstance(config.project, dict):
        if plant.path is None:
            raise ProjectError("the plant has no file to write")
        text = plant.path.read_text(encoding="utf-8")
        name = next((n for n in config.project if _lookup(params, n) is param), None)
        lines = text.splitlines(keepends=True)
        if name is None:
            raise ProjectError(f"the project of {device} does not name {param.label or param.name}: add it to the plant file")
        line = _entry_line(text, config.line, name)
        match = _name_pattern(name).search(lines[line - 1])
        if match is None:
            raise ProjectError(f"{plant.path}:{line}: cannot find {name} = ... to rewrite")
        head = lines[line - 1][:match.end()]
        rest = lines[line - 1][match.end():]
        old = re.match(r'("(?:[^"\\]|\\.)*"|[^,}#\n]*?)(\s*(?:[,}#]|\n|$))', rest)
        lines[line - 1] = head + _toml_value(value) + rest[len(old.group(1)):]
        new_text = "".join(lines)
        try:
            new_plant = parse_plant(new_text, plant.path)
        except PlantError as exc:
            raise ProjectError(f"the rewritten plant file would not load: {exc}") from None
        if new_plant.devices[device].project.get(name) != value:
            raise ProjectError(f"{plant.path}:{line}: the rewrite did not give {name} = {value}")
        backup.write_atomic(plant.path, new_text)
        config.project = new_plant.devices[device].project
        return next(e for e in entries(plant, device) if e.key == key)
    path = project_file(plant, device)
    if path is None:
        raise ProjectError(f"{device}: the plant file names no project for it")
    data = json.loads(path.read_text(encoding="utf-8"))
    for item in data.get("parameters", []):
        if item.get("key") == key:
            item.update(value=param.decode(raw), raw=raw, text=param.display(raw))
            break
    else:
        data.setdefault("parameters", []).append(
            {"key": key, "name": param.label or param.name, "space": param.space, "address": param.address, "raw": raw,
             "value": param.decode(raw), "text": param.display(raw), "unit": param.unit, "writable": True})
    backup.load_document(json.dumps(data), str(path))  # still a readable parameter file
    backup.write_atomic(path, json.dumps(data, indent=2, ensure_ascii=False))
    return next(e for e in entries(plant, device) if e.key == key)


# -- commission check --------------------------------------------------------------------------------


def add_parser(sub) -> None:
    parser = sub.add_parser("check", help="check a plant file and its devices' projects without the devices")
    parser.add_argument("--plant", type=Path, required=True, help="plant file")
    parser.set_defaults(func=run_cli)


def run_cli(args: argparse.Namespace) -> int:
    try:
        plant = load_plant(args.plant)
    except PlantError as exc:
        print(exc, file=sys.stderr)
        return 2
    problems = check_plant(plant)
    for problem in problems:
        print(problem)
    counted = sum(len(entries(plant, d)) for d in plant.devices if has_project(plant, d))
    print(f"{args.plant}: {len(plant.devices)} devices, {counted} project entries, "
          f"{len(problems)} invalid or unknown", file=sys.stderr if problems else sys.stdout)
    return 1 if problems else 0
