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

Without the device (it may never have answered), :func:`save` sets, adds and drops entries on the type's
parameter model (:func:`editable`, :func:`allowed`, :func:`parse_value`): an inline table, a
``[device.project]`` table, a new ``project = { ... }`` line or the parameter file is rewritten atomically,
its other content and comments kept and the old file kept as ``<name>.bak``.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from app import backup, files
from app.capabilities import allowed_text
from app import cli_lang
from app.cli_lang import _
from app.i18n import N_
from app.message import Message, joined, message_of, said
from app.plant import Plant, PlantError, load_plant, parse_plant
from devices.errors import CommissionError
from devices.params import Param, ParamError
from devices.registry import DEVICE_TYPES


class ProjectError(CommissionError, ValueError):
    """A project that cannot be read or changed; the message (a :class:`~app.message.Message`) names file and line."""


NO_FILE = N_("the plant has no file to write")
NO_LONGER_LOADS = N_("the plant file no longer loads ({error}): fix it, then reload the project")
NOT_NAMED = N_("{path} no longer names device '{device}' (changed meanwhile): reload")


@dataclass
class ProjectEntry:
    device: str
    name: str  # as the project names it
    value: Any
    file: str
    line: int
    key: str = ""  # the parameter's key when the model knows it
    raw: int | None = None  # what would be written, when valid
    error: str = ""  # what is wrong, a :class:`~app.message.Message` (or the parameter model's own words)
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
        return None, None, Message(N_("this device type has no parameter model: its project cannot be checked or applied"))
    param = _lookup(params, name)
    if param is None:
        close = [p for p in params.by_name if p.lower().startswith(name.lower()[:6])][:3]
        if close:
            return None, None, Message(N_("unknown parameter {name!r}; did you mean {close}?"), name=name, close=", ".join(close))
        return None, None, Message(N_("unknown parameter {name!r}"), name=name)
    if isinstance(value, bool) or not isinstance(value, int | float | str):
        return param, None, Message(N_("{name}: {value!r} is not a number or an enum name"), name=name, value=value)
    try:
        raw = param.validate(value)
    except ParamError as exc:
        return param, None, message_of(exc)
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
        text = files.read_regular_text(path, files.MAX_DOCUMENT_BYTES, "parameter file")
        document = backup.load_document(text, str(path))
    except files.FileRefused as exc:
        return [ProjectEntry(device, "", None, where, config.line, error=Message(N_("project file {error}"), error=exc))]
    except OSError as exc:
        return [ProjectEntry(device, "", None, where, config.line,
                             error=Message(N_("project file {path}: {error}"), path=path, error=exc.strerror or exc))]
    except UnicodeDecodeError:
        return [ProjectEntry(device, "", None, where, config.line,
                             error=Message(N_("project file {path}: not UTF-8 text (a backup file is JSON)"), path=path))]
    except backup.BackupError as exc:
        return [ProjectEntry(device, "", None, str(path), 1, error=message_of(exc))]
    doc_type = document["device"].get("type")
    if doc_type != config.type:
        return [ProjectEntry(device, "", None, str(path), 1,
                             error=Message(N_("the parameter file is of a {type!r}, device '{device}' is a {device_type!r}"),
                                           type=doc_type, device=device, device_type=config.type))]
    lines = text.splitlines()
    for item in document["parameters"]:
        if not item.get("writable"):
            continue  # read-only entries are kept for reference, never written
        key = item["key"]
        line = next((i + 1 for i, t in enumerate(lines) if f'"{key}"' in t), 1)
        entry = ProjectEntry(device, item["name"], item.get("value"), str(path), line)
        param = params.by_key.get(key) if params is not None else None
        if param is None and params is not None:
            entry.error = Message(N_("unknown parameter {name!r} ({key})"), name=item["name"], key=key)
        else:
            entry.param, entry.raw, entry.error = _check(params, device, param.label or param.name if param else item["name"],
                                                         item.get("value"))
            if not entry.error and "raw" in item and item["raw"] != entry.raw:
                entry.error = Message(N_("{name}: raw {raw!r} and value {value!r} disagree"), name=item["name"], raw=item["raw"],
                                      value=item.get("value"))
        entry.key = entry.param.key if entry.param is not None else key
        found.append(entry)
    return found


def check_plant(plant: Plant) -> list[str]:
    """Every invalid or unknown project entry of the plant, as ``file:line: device 'x': problem``."""
    problems = []
    for name in plant.devices:
        for entry in entries(plant, name):
            if entry.error:
                problems.append(Message(N_("{where}: device '{name}': {problem}"), where=entry.where, name=name, problem=entry.error))
    return problems


def has_project(plant: Plant, device: str) -> bool:
    config = plant.devices.get(device)
    return config is not None and config.project is not None


def document(runtime, device: str) -> dict:
    """The device's project as a backup document: every entry, valid or not (an invalid one shows in
    restore's diff as "not written" with the reason)."""
    plant = runtime.plant
    if not has_project(plant, device):
        raise backup.BackupError(Message(N_("{device}: the plant file names no project for it"), device=device))
    state = runtime.store.devices[device]
    items = []
    for entry in entries(plant, device):
        if not entry.key:
            continue
        item = {"key": entry.key, "name": entry.param.label or entry.param.name if entry.param else entry.name,
                "value": entry.value, "writable": True}
        if entry.param is not None and entry.raw is not None:
            # the number the entry stands for: an enum's name (``Kraftüberwachung = "ohne"``) is applied as its value
            item.update(raw=entry.raw, unit=entry.param.unit, text=entry.param.display(entry.raw),
                        value=entry.param.decode(entry.raw))
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
    params = DEVICE_TYPES[plant.devices[device].type].params
    param = params.by_key.get(key) if params is not None else None
    if param is None:
        raise ProjectError(Message(N_("{key} is not a parameter of {device}"), key=repr(key), device=device))
    if not any(e.key == key for e in entries(plant, device)):
        raise ProjectError(Message(N_("the project of {device} does not name {name}: add it to the plant file"), device=device,
                                   name=param.label or param.name))
    save(plant, device, {key: value})
    return next(e for e in entries(plant, device) if e.key == key)


# -- editing a project on the type's parameter model (the /project/<device> view) ----------------------------


def editable(plant: Plant, device: str) -> list[Param]:
    """The parameters a project of ``device`` may name: every writable one of its type's parameter model
    ([] for a type without one)."""
    params = DEVICE_TYPES[plant.devices[device].type].params
    return [] if params is None else [p for p in params if p.writable]


def allowed(param: Param) -> str:
    """What an entry of ``param`` may be, in words: "0 .. 65535 ms (whole numbers)", "one of: 0 Off, 1 On" (a
    :class:`~app.message.Message` but for the parameter model's own words)."""
    if text := allowed_text(param):  # a value that is not a number says itself (an M3IO record's bytes)
        return text
    if param.enum is not None:
        return Message(N_("one of: {values}"), values=", ".join(f"{number} {name}" for number, name in param.enum.items()))
    low, high = param.limits()
    number = (lambda x: f"{x:g}") if param.scale != 1 else (lambda x: str(int(x)))
    span = f"{number(low)} .. {number(high)} {param.unit}".rstrip()
    if param.scale != 1:
        return Message(N_("{range} in steps of {step}"), range=span, step=f"{param.scale:g}")
    return Message(N_("{range} (whole numbers)"), range=span)


def parse_value(param: Param, text: str | int | float) -> int | float:
    """An entry as typed (a number, or an enum's name) -> the value the project keeps (the decoded number).

    :raises ProjectError: not a number, out of range, no enum value; the message says what is allowed
    """
    if isinstance(text, str) and not text.strip():
        raise ProjectError(Message(N_("{name}: empty; allowed: {allowed}"), name=param.label or param.name, allowed=allowed(param)))
    try:
        raw = param.validate(text)
    except ParamError as exc:
        message = message_of(exc)
        if "outside" in message or "not one of" in message:
            raise ProjectError(message) from None
        raise ProjectError(Message(N_("{error}; allowed: {allowed}"), error=message, allowed=allowed(param))) from None
    return param.decode(raw)


def _bare_key(name: str) -> str:
    return name if re.fullmatch(r"[A-Za-z0-9_-]+", name) else json.dumps(name)


def _outside_strings(text: str):
    """``(index, char, depth)`` of every character of TOML ``text`` outside its strings; depth counts the brackets
    and braces open before it."""
    depth, quote, escaped = 0, "", False
    for i, ch in enumerate(text):
        if quote:
            if escaped:
                escaped = False
            elif ch == "\\" and quote == '"':
                escaped = True
            elif ch == quote:
                quote = ""
            continue
        if ch in "\"'":
            quote = ch
            continue
        if ch in "]}":
            depth -= 1
        yield i, ch, depth
        if ch in "[{":
            depth += 1


def _split_items(inner: str) -> list[str]:
    """The ``key = value`` items of an inline table's inside, split on its top-level commas."""
    cuts = [i for i, ch, depth in _outside_strings(inner) if ch == "," and depth == 0]
    bounds = zip([-1] + cuts, cuts + [len(inner)])
    return [inner[a + 1:b].strip() for a, b in bounds if inner[a + 1:b].strip()]


def _closing_brace(line: str, opening: int) -> int:
    for i, ch, depth in _outside_strings(line[opening:]):
        if ch == "}" and depth == 0:
            return opening + i
    raise ProjectError(Message(N_("the project's inline table does not close on its line")))


def _rewrite_inline(line: str, changes: dict[str, Any]) -> str:
    """``project = { ... }`` with ``changes`` (name -> value, None to drop) applied; other items kept as written."""
    opening = line.index("{", line.index("="))
    closing = _closing_brace(line, opening)
    items = []
    done = set()
    for item in _split_items(line[opening + 1:closing]):
        key_text = item.split("=", 1)[0].strip()
        name = json.loads(key_text) if key_text.startswith('"') else key_text.strip("'")
        if name in changes:
            done.add(name)
            if changes[name] is None:
                continue
            item = f"{key_text} = {_toml_value(changes[name])}"
        items.append(item)
    items += [f"{_bare_key(n)} = {_toml_value(v)}" for n, v in changes.items() if n not in done and v is not None]
    table = "{ " + ", ".join(items) + " }" if items else "{}"
    return line[:opening] + table + line[closing + 1:]


def _rewrite_table(lines: list[str], header: int, end: int, changes: dict[str, Any]) -> None:
    """The lines of a ``[device.project]`` table (header on 0-based ``header``, up to ``end``) with ``changes``."""
    done, last = set(), header
    for i in range(end - 1, header, -1):
        text = lines[i]
        if not text.strip() or text.lstrip().startswith("#"):
            continue
        last = max(last, i)
        name = next((n for n in changes if _name_pattern(n).search(text)), None)
        if name is None:
            continue
        done.add(name)
        if changes[name] is None:
            del lines[i]
            last -= 1
            continue
        match = _name_pattern(name).search(text)
        rest = text[match.end():]
        old = re.match(r'("(?:[^"\\]|\\.)*"|[^#\n]*?)(\s*(?:#|\n|$))', rest)
        lines[i] = text[:match.end()] + _toml_value(changes[name]) + rest[len(old.group(1)):]
    added = [f"{_bare_key(n)} = {_toml_value(v)}\n" for n, v in changes.items() if n not in done and v is not None]
    lines[last + 1:last + 1] = added


def _new_inline(lines: list[str], span: range, changes: dict[str, Any]) -> None:
    """A ``project = { ... }`` line after the device table's last key (before any sub-table of it)."""
    end = next((i for i in span if i > span.start and re.match(r"^\s*\[", lines[i])), span.stop)
    last = max((i for i in range(span.start, end) if lines[i].strip() and not lines[i].lstrip().startswith("#")),
               default=span.start)
    items = ", ".join(f"{_bare_key(n)} = {_toml_value(v)}" for n, v in changes.items() if v is not None)
    if not lines[last].endswith("\n"):
        lines[last] += "\n"
    lines.insert(last + 1, f"project = {{ {items} }}\n")


def _names_for(config, params, changes: dict[str, Any]) -> dict[str, Any]:
    """``changes`` by key -> by the name the project uses (its own spelling, else the parameter's label or name)."""
    named = {}
    for key, value in changes.items():
        param = params.by_key[key]
        project = config.project if isinstance(config.project, dict) else {}
        name = next((n for n in project if _lookup(params, n) is param), param.label or param.name)
        named[name] = value
    return named


def _write_with_backup(path: Path, old_text: str, new_text: str) -> None:
    """``path`` rewritten atomically where it points (a symlink stays a link), with its mode; what it held
    before is kept beside it as ``<name>.bak``. A read-only file is refused with the reason, before
    anything is written. A save that changes nothing writes nothing (the .bak keeps the file as it was
    before the last real change)."""
    if new_text == old_text:
        return
    try:
        target = files.writable_target(path)
        backup.write_atomic(target.with_name(target.name + ".bak"), old_text)
        files.replace_atomic(target, new_text)
    except files.FileRefused as exc:
        raise ProjectError(message_of(exc)) from None
    except OSError as exc:
        raise ProjectError(Message(N_("{path}: cannot be written ({error}): nothing saved"), path=path,
                                   error=exc.strerror or exc)) from None


def _fresh_plant(plant: Plant) -> Plant:
    """The plant file as it is on disk now (another page, a text editor may have changed it)."""
    if plant.path is None:
        raise ProjectError(Message(NO_FILE))
    try:
        return parse_plant(plant.path.read_text(encoding="utf-8"), plant.path)
    except PlantError as exc:
        raise ProjectError(Message(NO_LONGER_LOADS, error=message_of(exc))) from None
    except OSError as exc:
        raise ProjectError(Message(N_("{path}: cannot be read ({error})"), path=plant.path, error=exc.strerror or exc)) from None


def _save_inline(plant: Plant, device: str, changes: dict[str, Any]) -> None:
    """``changes`` (by key) into the device's inline or ``[device.project]`` table, on the file as it is now."""
    if plant.path is None:
        raise ProjectError(Message(NO_FILE))
    text = plant.path.read_text(encoding="utf-8")
    try:
        current = parse_plant(text, plant.path)
    except PlantError as exc:
        raise ProjectError(Message(NO_LONGER_LOADS, error=message_of(exc))) from None
    config = current.devices.get(device)
    if config is None:
        raise ProjectError(Message(NOT_NAMED, path=plant.path, device=device))
    if isinstance(config.project, str):
        raise ProjectError(Message(N_("{path}: the project of {device} is now a parameter file (changed meanwhile): reload"),
                                   path=plant.path, device=device))
    named = _names_for(config, DEVICE_TYPES[config.type].params, changes)
    lines = text.splitlines(keepends=True)
    span = _device_span(lines, config.line)
    inline = next((i for i in span if re.match(r"^\s*project\s*=\s*\{", lines[i])), None)
    table = next((i for i in span if re.match(r"^\s*\[\s*device\s*\.\s*project\s*\]", lines[i])), None)
    if inline is not None:
        lines[inline] = _rewrite_inline(lines[inline], named)
    elif table is not None:
        end = next((i for i in span if i > table and re.match(r"^\s*\[", lines[i])), span.stop)
        _rewrite_table(lines, table, end, named)
    else:
        _new_inline(lines, span, named)
    new_text = "".join(lines)
    expected = {**(config.project or {})}
    for name, value in named.items():
        if value is None:
            expected.pop(name, None)
        else:
            expected[name] = value
    try:
        new_plant = parse_plant(new_text, plant.path)
    except PlantError as exc:
        raise ProjectError(Message(N_("the rewritten plant file would not load: {error}"), error=message_of(exc))) from None
    if new_plant.devices[device].project != expected:
        raise ProjectError(Message(N_("{path}: the rewrite would not give the project asked for: nothing written"), path=plant.path))
    _write_with_backup(plant.path, text, new_text)
    running = plant.devices[device]
    running.project, running.line = new_plant.devices[device].project, new_plant.devices[device].line


def _save_file(path: Path, params, changes: dict[str, Any]) -> None:
    text = path.read_text(encoding="utf-8")
    data = json.loads(text)
    items = data.setdefault("parameters", [])
    for key, value in changes.items():
        param = params.by_key[key]
        found = next((item for item in items if item.get("key") == key), None)
        if value is None:
            if found is not None:
                items.remove(found)
            continue
        raw = param.validate(value)
        if found is None:
            found = {"key": key, "name": param.label or param.name, "space": param.space, "address": param.address,
                     "unit": param.unit, "writable": True}
            items.append(found)
        found.update(value=param.decode(raw), raw=raw, text=param.display(raw))
    new_text = json.dumps(data, indent=2, ensure_ascii=False)
    backup.load_document(new_text, str(path))  # still a readable parameter file
    _write_with_backup(path, text, new_text)


def _now(name: str, value: Any) -> Message:
    """An entry another save changed, as the project holds it now (``value`` None: dropped from it)."""
    if value is None:
        return Message(N_("{name} is now not in the project"), name=name)
    return Message(N_("{name} is now {value}"), name=name, value=value)


_SAVING = threading.Lock()  # project saves one at a time: each reads the file it changes, then writes it


def save(plant: Plant, device: str, changes: dict[str, Any], expected: dict[str, Any] | None = None) -> list[ProjectEntry]:
    """Set the project's entries of ``device``: ``changes`` maps a parameter key to its new value, or to None to
    drop the entry. Each value is checked by the parameter model first; the plant file (an inline table, a
    ``[device.project]`` table, or a new ``project = { ... }`` line) or the parameter file is rewritten atomically,
    its other content and comments kept, the old file kept as ``.bak``; the running plant follows.

    Saves are serialised, and each re-reads the file it changes, so two at the same moment both land and an
    edit made outside is kept. ``expected`` (key -> the value the editor showed, None for none) refuses the
    save when one of the changed entries is no longer what the editor showed: "changed meanwhile, reload".

    :raises ProjectError: an invalid value, a type without a parameter model, a file that cannot be rewritten,
        an entry changed meanwhile
    """
    config = plant.devices[device]
    params = DEVICE_TYPES[config.type].params
    if params is None:
        raise ProjectError(Message(N_("{device}: its type has no parameter model a project can be written in"), device=device))
    checked = {}
    for key, value in changes.items():
        param = params.by_key.get(key)
        if param is None or not param.writable:
            raise ProjectError(Message(N_("{key} is not a writable parameter of {device}"), key=repr(key), device=device))
        checked[key] = None if value is None else parse_value(param, value)
    if not checked:
        return entries(plant, device)
    with _SAVING:
        if expected is not None:
            source = plant if isinstance(config.project, str) else _fresh_plant(plant)
            if device not in source.devices:
                raise ProjectError(Message(NOT_NAMED, path=plant.path, device=device))
            now = {e.key: e.value for e in entries(source, device) if e.key}
            # changed by someone else since the editor showed it, and not to what this save asks for anyway
            moved = [k for k in checked if k in expected and now.get(k) != expected[k] and now.get(k) != checked[k]]
            if moved:
                words = joined([_now(params.by_key[k].label or params.by_key[k].name, now.get(k)) for k in moved])
                raise ProjectError(Message(N_("the project of {device} was changed meanwhile ({changes}): nothing saved; reload the "
                                              "project and make the change again"), device=device, changes=words))
        if isinstance(config.project, str):
            _save_file(project_file(plant, device), params, checked)
        else:
            _save_inline(plant, device, checked)
    return entries(plant, device)


# -- commission check --------------------------------------------------------------------------------


def add_parser(sub) -> None:
    parser = sub.add_parser("check", help=_("check a plant file and its devices' projects without the devices"))
    parser.add_argument("--plant", type=Path, required=True, help=_("plant file"))
    parser.set_defaults(func=run_cli)


def run_cli(args: argparse.Namespace) -> int:
    try:
        plant = load_plant(args.plant)
    except PlantError as exc:
        print(said(exc, cli_lang.lang()), file=sys.stderr)
        return 2
    problems = check_plant(plant)
    for problem in problems:
        print(said(problem, cli_lang.lang()))
    counted = sum(len(entries(plant, d)) for d in plant.devices if has_project(plant, d))
    print(_("{plant}: {devices} devices, {entries} project entries, {problems} invalid or unknown").format(
        plant=args.plant, devices=len(plant.devices), entries=counted, problems=len(problems)),
        file=sys.stderr if problems else sys.stdout)
    return 1 if problems else 0
