"""Widgets shared by device pages: lamps, register tables, live charts, write dialogs."""

from __future__ import annotations

import time
from collections.abc import Awaitable, Callable
from datetime import datetime

from nicegui import ui

from app import runtime as rt
from app.state import DeviceState
from app.worker import PermissionDenied
from devices.params import Param, ParamError

CHART_WINDOW_S = 300


def session_role() -> str:
    """Role of the browser session (engineer on loopback, else the account's role)."""
    from pages.session import current_user

    return current_user()[1]


class Lamp:
    """A named indicator light; ``kind`` "ok" (green), "warn" (yellow) or "alarm" (red)."""

    def __init__(self, name: str, kind: str = "ok", tooltip: str = ""):
        with ui.row().classes("items-center gap-1 no-wrap") as self.row:
            self.dot = ui.element("span").classes(f"lamp {'' if kind == 'ok' else kind}")
            ui.label(name).classes("text-body2")
            if tooltip:
                ui.tooltip(tooltip)
        self.row.props(f'data-lamp="{name}"')
        self.kind = kind

    def set(self, on: bool | None) -> None:
        self.dot.classes(remove="on unknown")
        if on is None:
            self.dot.classes(add="unknown")
        elif on:
            self.dot.classes(add="on")
        self.row.props(f'data-on="{"unknown" if on is None else int(bool(on))}"')

    def show(self, entry: dict | None, value=None) -> None:
        """Show a live point (its value, or ``value`` taken from it) with its quality: offline shows unknown."""
        quality = "unknown" if entry is None else entry["quality"]
        self.set(None if entry is None or quality == "offline" else bool(entry["value"] if value is None else value))
        mark_quality(self.row, quality)


QUALITY_CLASSES = "q-stale q-offline q-unknown"


def entry_age(entry: dict | None) -> float | None:
    import time

    return None if entry is None or entry.get("time") is None else max(0.0, time.time() - entry["time"])


def quality_note(quality: str, age: float | None) -> str:
    """The words shown next to a value that is not good: ``stale 12 s``, ``offline, last 2 min``."""
    from pages.frame import fmt_age

    if quality == "stale":
        return f"stale {fmt_age(age)}"
    if quality == "offline":
        return f"offline, last {fmt_age(age)}" if age is not None else "offline"
    if quality == "unknown":
        return "not read"
    return ""


def mark_quality(element: ui.element, quality: str) -> None:
    """Grey an element by the quality of the value it shows (classes q-stale, q-offline, q-unknown)."""
    element.classes(remove=QUALITY_CLASSES)
    if quality in ("stale", "offline", "unknown"):
        element.classes(add=f"q-{quality}")
    element.props(f'data-quality="{quality}"')


class LiveValue:
    """A label showing one live point of the store with its quality (greyed, with its age, when not good)."""

    def __init__(self, state: DeviceState, point: str, fmt=None, classes: str = "text-body1"):
        self.state, self.point, self.fmt = state, point, fmt
        with ui.row().classes("items-baseline gap-0 no-wrap") as self.row:
            self.label = ui.label("-").classes(classes)
            self.age = ui.label().classes("q-age")
        self.row.props(f'data-point="{point}"')
        self.update()

    def update(self) -> None:
        import time

        entry = self.state.point(self.point)
        if entry is None:
            self.label.set_text("-")
            quality, age = "unknown", None
        else:
            self.label.set_text(self.fmt(entry) if self.fmt else (entry["text"] if entry["text"] is not None else
                                                                   f"{entry['value']} {entry['unit']}".strip()))
            quality = entry["quality"]
            age = None if entry["time"] is None else max(0.0, time.time() - entry["time"])
        mark_quality(self.row, quality)
        self.age.set_text(quality_note(quality, age) if quality in ("stale", "offline") else "")


REGISTER_COLUMNS = [
    {"name": "address", "label": "Addr", "field": "address", "align": "right", "sortable": True},
    {"name": "name", "label": "Name", "field": "name", "align": "left"},
    {"name": "value", "label": "Value", "field": "value", "align": "left"},
    {"name": "raw", "label": "Raw", "field": "raw", "align": "left", "classes": "mono"},
    {"name": "access", "label": "Access", "field": "access", "align": "center"},
    {"name": "age", "label": "Read", "field": "age", "align": "right"},
    {"name": "quality", "label": "Quality", "field": "quality", "align": "left"},
]


class RegisterTable:
    """Live table of one register space of a device (address, name, value, raw, access)."""

    def __init__(self, state: DeviceState, params: list[Param]):
        self.state = state
        self.params = params
        self.table = ui.table(columns=REGISTER_COLUMNS, rows=[], row_key="key", pagination=0).classes("w-full reg-table")
        self.table.props("dense flat bordered")
        self.table.add_slot(
            "body-cell-name",
            '<q-td :props="props" :title="props.row.description" style="cursor: help">'
            '{{ props.value }}<q-badge v-if="props.row.unsaved" color="orange" class="q-ml-xs">unsaved</q-badge></q-td>',
        )
        self.table.props(':table-row-class-fn="row => row.quality_class"')
        self.update()

    def update(self) -> None:
        import time

        rows = []
        now = time.time()
        for p in self.params:
            raw = self.state.raw(p)
            read = self.state.read_time(p)
            quality = self.state.quality(read, self.state.registers_periodic, now)
            rows.append({
                "key": p.key,
                "address": p.address if p.words == 1 else f"{p.address}-{p.address + p.words - 1}",
                "name": p.label or p.name,
                "value": "-" if raw is None else p.display(raw),
                "raw": "-" if raw is None else f"0x{raw:0{4 * p.words}X}",
                "access": p.access.value + (" (never written)" if p.never_write and p.access.value == "RW" else ""),
                "age": "-" if read is None else datetime.fromtimestamp(read).strftime("%H:%M:%S"),
                "description": p.description,
                "unsaved": p.key in self.state.unsaved,
                "quality": quality if raw is not None else "-",  # the Read column gives its age; the row stays put between reads
                "quality_class": f"q-{quality}" if quality in ("stale", "offline") else "",
            })
        if rows != self.table.rows:
            self.table.rows = rows
            self.table.update()


class HistoryChart:
    """Rolling plotly time chart of the device history samples."""

    @staticmethod
    def _iso(t: float) -> str:
        return datetime.fromtimestamp(t).isoformat(timespec="milliseconds")

    def __init__(self, state: DeviceState, series: list[str], window_s: int = CHART_WINDOW_S, height: int = 320):
        self.state = state
        self.series = series
        self.window_s = window_s
        self.figure = {
            "data": [{"type": "scatter", "mode": "lines", "name": s, "x": [], "y": []} for s in series],
            "layout": {
                "margin": {"l": 50, "r": 10, "t": 10, "b": 40},
                "height": height,
                "xaxis": {"type": "date"},
                "legend": {"orientation": "h", "y": -0.2},
                "showlegend": True,
                "uirevision": "keep",
            },
            "config": {"displaylogo": False, "responsive": True},
        }
        self.plot = ui.plotly(self.figure).classes("w-full")
        self.update()

    def update(self) -> None:
        layout = self.figure["layout"]
        if not self.state.history:
            if not layout.get("annotations"):  # nothing read yet: the last window up to now, not an axis at 1970/2000
                now = time.time()
                layout["xaxis"].update(autorange=False, range=[self._iso(now - self.window_s), self._iso(now)])
                layout["annotations"] = [{"text": "no data yet", "xref": "paper", "yref": "paper", "x": 0.5, "y": 0.5,
                                          "showarrow": False, "font": {"size": 16, "color": "#757575"}}]
                self.plot.update()
            return
        if layout.pop("annotations", None) is not None:
            layout["xaxis"].pop("range", None)
            layout["xaxis"]["autorange"] = True
        last = self.state.history[-1][0]
        samples = [(t, s) for t, s in self.state.history if t >= last - self.window_s]
        xs = [self._iso(t) for t, _ in samples]
        for trace, name in zip(self.figure["data"], self.series):
            trace["x"] = xs
            trace["y"] = [s.get(name) for _, s in samples]
        self.plot.update()


async def confirm(title: str, text: str, ok: str = "Continue", danger: bool = True) -> bool:
    """Modal confirmation; resolves True only when the engineer presses ``ok``."""
    with ui.dialog() as dialog, ui.card().classes("max-w-lg"):
        ui.label(title).classes("text-h6")
        ui.label(text).classes("text-body1" + (" text-negative" if danger else ""))
        with ui.row().classes("justify-end w-full"):
            ui.button("Cancel", on_click=lambda: dialog.submit(False)).props("flat")
            ui.button(ok, color="negative" if danger else "primary", on_click=lambda: dialog.submit(True))
    result = await dialog
    dialog.delete()
    return bool(result)


async def run_command(
    device: str, action: Callable[[object], Awaitable[object]], describe: str, success: str = "", write: bool = True,
    parameter: str = "", old: object = "", new: object = "",
) -> tuple[bool, object]:
    """Submit a command to the worker and report the outcome as a notification.

    ``write=False`` for reads and for actions that only make a device safer (stop, release).
    """
    from pages.session import current_user

    user, role = current_user()
    try:
        result = await rt.current().worker.command(
            device, action, role=role, user=user or "anonymous", describe=describe, write=write,
            record=write or not describe.startswith("read"), parameter=parameter, old=old, new=new,
        )
    except PermissionDenied as exc:
        ui.notify(str(exc), type="negative")
        return False, None
    except Exception as exc:  # every adapter error carries a message for the engineer
        ui.notify(f"{describe}: {exc}", type="negative", multi_line=True, close_button="OK", timeout=15000)
        return False, None
    if success:
        ui.notify(success, type="positive")
    return True, result


async def write_from_page(device: str, param: Param, value, *, success: str, title: str = "", ok: str = "Write anyway") -> None:
    """An engineer's entry for one parameter: check it, ask when the parameter wants a
    confirmation, then write through the worker with old and new value for the audit log."""
    if value is None or value == "":
        ui.notify(f"{param.name}: enter a value first", type="warning")
        return
    try:
        raw = param.validate(value)
    except ParamError as exc:
        ui.notify(str(exc), type="negative")
        return
    warning = param.needs_confirmation(raw)
    title = (title or "Write {name} = {value}?").format(name=param.name, value=param.display(raw))
    if warning and not await confirm(title, warning, ok=ok):
        return
    before = rt.current().store.devices[device].raw(param)
    await run_command(
        device,
        lambda a: a.write_param(param, param.decode(raw), confirmed=bool(warning)),
        f"write {param.name}",
        success=success.format(name=param.name, value=param.display(raw)),
        parameter=param.label or param.name, old="" if before is None else param.display(before), new=param.display(raw),
    )
