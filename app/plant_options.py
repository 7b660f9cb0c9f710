"""Device options the running tool keeps in the plant file (an M3IO's P2, which the module forgets at a reset).

An adapter says what the plant file should hold (``plant_options()``); the running plant follows at once
and the file is rewritten in place (its comments and layout kept), checked first by loading it again
(app/plant.py), then replaced atomically.
"""

from __future__ import annotations

import os
import re
import tempfile
from pathlib import Path
from typing import Any

from app.plant import DEMO_PLANT, Plant, PlantError, parse_plant
from devices.message import Message, N_


def _option_toml(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int | float):
        return repr(value)
    return '"' + str(value).replace("\\", "\\\\").replace('"', '\\"') + '"'


def set_device_options(path: Path, device: str, options: dict[str, Any]) -> bool:
    """Set ``options`` (key -> true/false, a number or a text) in the ``[[device]]`` table named ``device`` of the
    plant file at ``path``: a key's line is rewritten (its comment kept), a new key goes after the table's last key
    (before any sub-table); the rest of the file stays as written. Checked to load and to give these options, then
    replaced atomically. Returns False when the file holds them already.

    :raises PlantError: the file no longer loads, names no such device, or the rewrite would not give the options
    """
    text = path.read_text(encoding="utf-8")
    config = parse_plant(text, path).devices.get(device)
    if config is None:
        raise PlantError(f"{path} names no device '{device}'")
    wanted = {k: v for k, v in options.items() if config.options.get(k) != v}
    if not wanted:
        return False
    lines = text.splitlines(keepends=True)
    start = config.line - 1
    end = next((i for i in range(start + 1, len(lines)) if re.match(r"^\s*\[", lines[i])), len(lines))
    for key, value in wanted.items():
        pattern = re.compile(rf"^(\s*{re.escape(key)}\s*=\s*)(\"[^\"]*\"|[^#\n]*?)(\s*(?:#.*)?\n?)$")
        found = next((i for i in range(start + 1, end) if pattern.match(lines[i])), None)
        if found is not None:
            match = pattern.match(lines[found])
            lines[found] = match.group(1) + _option_toml(value) + match.group(3)
            continue
        last = max((i for i in range(start, end) if lines[i].strip() and not lines[i].lstrip().startswith("#")), default=start)
        if not lines[last].endswith("\n"):
            lines[last] += "\n"
        lines.insert(last + 1, f"{key} = {_option_toml(value)}\n")
        end += 1
    new_text = "".join(lines)
    rewritten = parse_plant(new_text, path).devices.get(device)
    if rewritten is None or any(rewritten.options.get(k) != v for k, v in wanted.items()):
        raise PlantError(f"{path}: the rewrite would not give device '{device}' {wanted}: nothing written")
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".part", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as handle:
            handle.write(new_text)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return True


def options_to_keep(plant: Plant, device: str, options: dict[str, Any]) -> dict[str, Any]:
    """Those of ``options`` the running plant does not hold for ``device`` yet (a flag that is absent counts as false)."""
    config = plant.devices.get(device)
    if config is None:
        return {}
    return {k: v for k, v in options.items() if config.options.get(k, False if isinstance(v, bool) else None) != v}


def keep_device_options(plant: Plant, device: str, options: dict[str, Any]) -> str:
    """Keep what an adapter says the plant file should hold for ``device`` (``plant_options()``, e.g. an M3IO's
    ``p2``): the running plant follows at once, the plant file is rewritten (:func:`set_device_options`), except
    the built-in demo plant, which this tool never rewrites. Returns what was done, in words ("" for nothing)."""
    changed = options_to_keep(plant, device, options)
    if not changed:
        return ""
    plant.devices[device].options.update(changed)
    words = ", ".join(f"{k} = {_option_toml(v)}" for k, v in changed.items())
    if plant.path is None or plant.path.resolve() == DEMO_PLANT.resolve():
        return Message(N_("{options} holds until this program ends: the built-in demo plant is not rewritten"), options=words)
    set_device_options(plant.path, device, changed)
    return Message(N_("{options} kept in the plant file {file}"), options=words, file=plant.path.name)
