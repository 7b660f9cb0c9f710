"""Live charts of a device's history (plotly), drawn incrementally and paused while the page is hidden."""

from __future__ import annotations

import json
import time
import weakref
from datetime import datetime
from pathlib import Path

from nicegui import Client, context, ui
from nicegui.element import Element

from app import i18n
from app.i18n import Lang
from app.state import DeviceState
from pages.widgets import follow

CHART_WINDOW_S = 300


# New samples for a chart, drawn with one extendTraces once plotly is loaded and the chart drawn (calls
# that come earlier wait, up to 10 s). While the page is hidden (another tab, a minimised window) nothing
# is drawn: samples that arrive meanwhile are merged, at most ``max`` per trace, and drawn in one go
# when the page is shown again. A whole new drawing of the chart drops what was waiting.
EXTEND_JS = """<script>
window.commissionExtend = function (id, update, idx, max) {
  const q = (window.__cx = window.__cx || {});
  const waiting = q[id];
  if (waiting) {
    for (let t = 0; t < update.x.length; t++) {
      waiting.u.x[t] = waiting.u.x[t].concat(update.x[t]).slice(-max);
      waiting.u.y[t] = waiting.u.y[t].concat(update.y[t]).slice(-max);
    }
    waiting.m = max;
  } else {
    q[id] = {u: update, i: idx, m: max};
  }
  window.__cxFlush(id, 0);
};
window.commissionRedrawn = function (id) { delete (window.__cx || {})[id]; };
window.__cxFlush = function (id, tries) {
  const q = window.__cx || {};
  const waiting = q[id];
  if (!waiting || document.hidden) return;
  const vm = getElement(id);
  if (!(vm && vm.Plotly && vm.$el && vm.$el.data)) {
    if (tries < 100) setTimeout(() => window.__cxFlush(id, tries + 1), 100); else delete q[id];
    return;
  }
  delete q[id];
  vm.Plotly.extendTraces(vm.$el, waiting.u, waiting.i, waiting.m);
};
document.addEventListener("visibilitychange", () => {
  if (!document.hidden) for (const id of Object.keys(window.__cx || {})) window.__cxFlush(id, 0);
});
</script>"""


_EXTENDED: weakref.WeakSet[Client] = weakref.WeakSet()  # the browser pages that have the chart's extend script


STATIC = Path(__file__).resolve().parent.parent / "static"


class _Plot(ui.plotly, component=STATIC / "history_plot.js", esm={"commission-plotly": str(STATIC / "plotly-basic")}):
    """A plotly element on plotly.js's basic bundle (the charts draw lines only: static/history_plot.js says what it
    saves the browser), that sends the figure as it is: NiceGUI's own keeps an observed copy of every list of the
    figure's data beside it (a second copy of the chart's window for each open page)."""

    def update(self) -> None:
        dict.__setitem__(self._props, "options", self._get_figure_json())
        Element.update(self)


class HistoryChart:
    """Rolling plotly time chart of the device history samples.

    The browser keeps the window: after the first drawing only new samples are sent (plotly
    ``extendTraces``, bounded by ``maxPoints``); a long window is thinned to at most
    :data:`MAX_POINTS` points. ``axes`` puts series on a second y axis (``{"Current [mA]": "y2"}``);
    ``rows`` stacks groups of series one above the other, each on its own y axis, over one time axis
    (``[["Position [mm]"], ["Current [A]"]]``, heights in the ratio of ``row_heights``): one figure
    and one drawing for all of them. ``windows`` offers window lengths to choose from (seconds, e.g.
    ``(30, 300)``). With ``lang`` the legend names the series by the catalog's entry of each name (the page marks
    them ``N_``; a name the catalog lacks is shown as it is), the axes write numbers the language's way and the
    empty chart says so in it.
    """

    MAX_POINTS = 1500
    MIN_PERIOD_S = 1.0  # new samples go to the browser once a second (values show at once elsewhere): a drawing costs
    # the browser as much as the rest of a device page

    @staticmethod
    def _iso(t: float) -> str:
        return datetime.fromtimestamp(t).isoformat(timespec="milliseconds")

    ROW_GAP = 0.08  # between stacked rows, as a share of the plotting height

    def __init__(self, state: DeviceState, series: list[str] | None = None, window_s: int = CHART_WINDOW_S,
                 height: int = 320, axes: dict[str, str] | None = None, windows: tuple[int, ...] = (),
                 rows: list[list[str]] | None = None, row_heights: tuple[float, ...] = (), lang: Lang | None = None):
        if (series is None) == (rows is None):
            raise ValueError("a chart takes either series or rows of series")
        row_axes = ["y" if i == 0 else f"y{i + 1}" for i in range(len(rows or ()))]  # top row first
        if rows is not None:
            axes = {name: axis for axis, row in zip(row_axes, rows) for name in row}
            series = [name for row in rows for name in row]
        self.state = state
        self.lang = lang or i18n.get("en")
        self.series = series
        self.window_s = window_s
        self.axes = axes or {}
        self.sent_t: float | None = None  # time of the newest sample in the browser
        self.sent_at = 0.0  # monotonic time of the last sending
        self.sent_points = 0  # samples sent since the last full drawing (for tests and measurements)
        self.drawn = False
        layout: dict = {
            "margin": {"l": 65, "r": 65 if self.axes and not rows else 30, "t": 10, "b": 40},  # room for ticks and titles
            "height": height,
            # fixed margins, tick labels not measured for overflow: each new drawing lays the chart out once;
            # time labels level (a narrow chart gets fewer, none cut off at the bottom)
            "xaxis": {"type": "date", "automargin": False, "ticklabeloverflow": "allow", "tickangle": 0},
            "yaxis": {"automargin": False, "ticklabeloverflow": "allow"},
            "legend": {"orientation": "h", "y": 1.02, "yanchor": "bottom", "x": 0},
            "showlegend": True,
            "uirevision": "keep",
        }
        symbols = self.lang.locale.number_symbols["latn"]
        if symbols["decimal"] != ".":
            layout["separators"] = symbols["decimal"] + symbols["group"]  # plotly's decimal and group signs: ",."

        def unit_of(name: str) -> str:  # a series keyed by a point's or parameter's own name: its unit
            value = state.live(name)
            param = state.params.by_name.get(name) if state.params is not None else None
            return (value.unit if value is not None else "") or (param.unit if param is not None else "") or name

        def units(names: list[str]) -> str:  # the axis titles name the units; the legend names the series
            found = [s[s.rfind("[") + 1:-1] if s.endswith("]") and "[" in s else unit_of(s) for s in names]
            return ", ".join(dict.fromkeys(found))

        def on(axis: str) -> list[str]:
            return [s for s in series if self.axes.get(s, "y") == axis]

        if rows:  # stacked, the first row on top; the time axis under the lowest
            weights = list(row_heights) or [1.0] * len(rows)
            share, top = (1.0 - self.ROW_GAP * (len(rows) - 1)) / sum(weights), 1.0
            for name, weight in zip(row_axes, weights):
                axis = layout.setdefault(name.replace("y", "yaxis"), {"automargin": False, "ticklabeloverflow": "allow"})
                axis.update(domain=[max(0.0, top - weight * share), top], anchor="x")
                axis["title"] = {"text": units(on(name))}
                top -= weight * share + self.ROW_GAP
            layout["xaxis"]["anchor"] = row_axes[-1]
        elif not self.axes and all(s.endswith("]") and "[" in s for s in series):
            layout["yaxis"]["title"] = {"text": units(series)}  # one axis: titled with its unit(s) too
        elif self.axes:
            layout["yaxis2"] = {"overlaying": "y", "side": "right", "title": {"text": units(on("y2"))}, "automargin": False,
                                "ticklabeloverflow": "allow", "showgrid": False}
            layout["yaxis"]["title"] = {"text": units(on("y"))}
        self.figure = {
            "data": [{"type": "scatter", "mode": "lines", "name": self.lang.gettext(s), "x": [], "y": [],
                      "yaxis": self.axes.get(s, "y")}
                     for s in series],
            "layout": layout,
            "config": {"displaylogo": False, "responsive": True},
        }
        if windows:
            options = {w: (f"{w // 60} min" if w >= 60 and w % 60 == 0 else f"{w} s") for w in windows}
            ui.toggle(options, value=window_s, on_change=lambda e: self.set_window(int(e.value))) \
                .props("dense size=sm no-caps").classes("self-end").props('data-chart-window')
        client = context.client
        if client not in _EXTENDED:
            ui.add_head_html(EXTEND_JS)
            _EXTENDED.add(client)
        self.plot = _Plot(self.figure).classes("w-full")
        self.max_points = self.MAX_POINTS
        self.update()
        follow(state, self.update)

    @property
    def step_s(self) -> float:
        """Shortest gap between two drawn samples: long windows are thinned to MAX_POINTS."""
        return self.window_s / self.MAX_POINTS

    def set_window(self, window_s: int) -> None:
        self.window_s = window_s
        self.sent_t = None  # draw the new window whole once
        self.update()

    def _thin(self, samples: list[tuple[float, dict]], after: float | None) -> list[tuple[float, dict]]:
        kept, last = [], after
        for t, sample in samples:
            if last is None or t - last >= self.step_s:
                kept.append((t, sample))
                last = t
        return kept

    def _columns(self, samples: list[tuple[float, dict]]) -> tuple[list[str], list[list]]:
        xs = [self._iso(t) for t, _ in samples]
        return xs, [[s.get(name) for _, s in samples] for name in self.series]

    def _max_points(self, samples: list[tuple[float, dict]]) -> int:
        """Points that fill the window at the rate seen (the browser drops older ones)."""
        if len(samples) < 2:
            return self.MAX_POINTS
        gap = max(self.step_s, (samples[-1][0] - samples[0][0]) / (len(samples) - 1))
        return max(10, min(self.MAX_POINTS, int(self.window_s / gap) + 1))

    def update(self) -> None:
        history = self.state.history
        layout = self.figure["layout"]
        if not history:
            if not layout.get("annotations"):  # nothing read yet: the last window up to now, not an axis at 1970/2000
                now = time.time()
                layout["xaxis"].update(autorange=False, range=[self._iso(now - self.window_s), self._iso(now)])
                layout["annotations"] = [{"text": self.lang.gettext("no data yet"), "xref": "paper", "yref": "paper", "x": 0.5, "y": 0.5,
                                          "showarrow": False, "font": {"size": 16, "color": "#757575"}}]
                self.plot.update()
            return
        newest = history[-1][0]
        if self.sent_t is not None and newest <= self.sent_t:
            return
        if self.sent_t is not None and time.monotonic() - self.sent_at < self.MIN_PERIOD_S:
            return  # the next push or the once-a-second round sends what came meanwhile
        self.sent_at = time.monotonic()
        if self.sent_t is None or newest - self.sent_t > self.window_s:
            self._redraw(newest)
            return
        fresh = []
        for sample in reversed(history):  # O(new samples), not a scan of the whole history
            if sample[0] <= self.sent_t:
                break
            fresh.append(sample)
        fresh.reverse()
        fresh = self._thin(fresh, self.sent_t)
        if not fresh:
            return
        xs, ys = self._columns(fresh)
        self.plot.client.run_javascript(
            f"window.commissionExtend({self.plot.id}, {json.dumps({'x': [xs] * len(self.series), 'y': ys})}, "
            f"{list(range(len(self.series)))}, {self.max_points})")
        self.sent_t = fresh[-1][0]
        self.sent_points += len(fresh)

    def _redraw(self, newest: float) -> None:
        layout = self.figure["layout"]
        if layout.pop("annotations", None) is not None:
            layout["xaxis"].pop("range", None)
            layout["xaxis"]["autorange"] = True
        samples = self._thin(self.state.history_since(self.window_s, now=newest), None)
        self.max_points = self._max_points(samples)
        xs, ys = self._columns(samples)
        for trace, column in zip(self.figure["data"], ys):
            trace["x"], trace["y"] = xs, column
        self.plot.update()  # (the figure keeps this drawing for a reconnecting browser; new samples only go out)
        if self.drawn:  # samples still waiting in a hidden page belong to the old drawing
            self.plot.client.run_javascript(f"window.commissionRedrawn && window.commissionRedrawn({self.plot.id})")
        self.drawn = True
        self.sent_t = samples[-1][0] if samples else newest
        self.sent_points = len(samples)
