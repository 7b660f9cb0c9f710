"""The two curves of docs/scale.md as PNG: the tool's CPU over its devices, and the site's latency over instances.

The figures are those of docs/scale.md's tables (bench/plant_scale.py and bench/site_scale.py), written here
by hand after a run. ReportLab's graphics draw each chart (as SVG: its PNG renderer needs a backend Debian
does not ship), and Debian's chromium, through playwright, turns the SVG into the PNG.

    python bench/scale_charts.py            # writes docs/scale-cost-per-device.png and docs/scale-site-latency.png
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from liveapp import CHROMIUM, CHROMIUM_ARGS, ROOT, need_playwright  # noqa: E402

# bench/plant_scale.py, 2026-11-28 (docs/scale.md): devices -> the tool's CPU, % of one core
TOOL_CPU = [(0, 0.4), (10, 5.2), (30, 9.2), (100, 19.4)]
TOOL_LOAD = "2026-11-28 08:30-08:36, load 6-10 on 2 cores shared with other work"
GOAL_PER_DEVICE = 0.1  # % of a core per idle device (issue 48)
# bench/site_scale.py: instances (20 devices each) -> publish-to-view latency p95, ms; one in flight, then 16
SITE_P95 = [(2, 402.0), (4, 257.0), (6, 220.0)]
SITE_P95_ONE_IN_FLIGHT = [(2, 107.0), (4, 169.0), (6, 1057.0)]
SITE_LOAD = "2026-11-28 08:46 and 09:06, load 15-28 on 2 cores shared with other work"
GOAL_P95_MS = 250.0


def chart(title: str, x_label: str, y_label: str, series: list[tuple[str, list[tuple[float, float]], str]],
          note: str, width: int = 760, height: int = 380):
    """A ReportLab drawing: ``series`` of (name, points, colour), the first with markers."""
    from reportlab.graphics.charts.legends import Legend
    from reportlab.graphics.charts.lineplots import LinePlot
    from reportlab.graphics.shapes import Drawing, String
    from reportlab.graphics.widgets.markers import makeMarker
    from reportlab.lib import colors

    drawing = Drawing(width, height)
    plot = LinePlot()
    plot.x, plot.y, plot.width, plot.height = 70, 60, width - 100, height - 152
    plot.data = [points for _, points, _ in series]
    for i, (_, _, colour) in enumerate(series):
        plot.lines[i].strokeColor = getattr(colors, colour)
        plot.lines[i].strokeWidth = 2
        if i == 0:
            plot.lines[i].symbol = makeMarker("FilledCircle")
            plot.lines[i].symbol.fillColor = getattr(colors, colour)
    xs = [x for _, points, _ in series for x, _ in points]
    ys = [y for _, points, _ in series for _, y in points]
    plot.xValueAxis.valueMin, plot.xValueAxis.valueMax = 0, max(xs) * 1.05
    plot.yValueAxis.valueMin, plot.yValueAxis.valueMax = 0, max(ys) * 1.15
    plot.xValueAxis.labels.fontName = plot.yValueAxis.labels.fontName = "Helvetica"
    drawing.add(plot)
    drawing.add(String(width / 2, height - 25, title, textAnchor="middle", fontName="Helvetica-Bold", fontSize=14))
    drawing.add(String(plot.x + plot.width / 2, 22, x_label, textAnchor="middle", fontName="Helvetica", fontSize=11))
    drawing.add(String(plot.x - 40, plot.y + plot.height + 12, y_label, textAnchor="start", fontName="Helvetica", fontSize=11))
    drawing.add(String(10, 6, note, textAnchor="start", fontName="Helvetica", fontSize=9, fillColor=colors.grey))
    legend = Legend()
    legend.alignment = "right"  # the colour first, then its name
    legend.x, legend.y = 20, height - 48  # one row under the title, outside the plot
    legend.columnMaximum, legend.deltax = 1, 250
    legend.fontName, legend.fontSize = "Helvetica", 10
    legend.colorNamePairs = [(getattr(colors, colour), name) for name, _, colour in series]
    drawing.add(legend)
    return drawing


def to_png(drawings: dict[Path, object]) -> None:
    """Each drawing as SVG (ReportLab), then as PNG through chromium."""
    from reportlab.graphics import renderSVG

    sync_playwright = need_playwright()
    with tempfile.TemporaryDirectory() as name, sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        for target, drawing in drawings.items():
            svg = Path(name) / (target.stem + ".svg")
            renderSVG.drawToFile(drawing, str(svg))
            page = browser.new_page(viewport={"width": int(drawing.width), "height": int(drawing.height)}, device_scale_factor=2)
            page.goto(svg.as_uri())
            page.screenshot(path=str(target), omit_background=False)
            page.close()
            print(f"wrote {target.relative_to(ROOT)}")
        browser.close()


def main() -> None:
    from statistics import fmean

    xs, ys = [x for x, _ in TOOL_CPU if x], [y for x, y in TOOL_CPU if x]
    mx, my = fmean(xs), fmean(ys)
    slope = sum((x - mx) * (y - my) for x, y in zip(xs, ys, strict=True)) / sum((x - mx) ** 2 for x in xs)
    base = my - slope * mx
    top = max(x for x, _ in TOOL_CPU)
    cost = chart("The tool's CPU over its devices (idle, no page open)", "devices in the plant", "% of one core",
                 [("measured", TOOL_CPU, "darkblue"),
                  (f"fit: {base:.1f} + {slope:.3f} per device", [(0, base), (top, base + slope * top)], "steelblue"),
                  (f"goal: {GOAL_PER_DEVICE} per device", [(0, base), (top, base + GOAL_PER_DEVICE * top)], "green")],
                 f"bench/plant_scale.py, {TOOL_LOAD}")
    site = chart("Publish-to-view latency p95 over instances (20 devices each)", "instances on one broker",
                 "p95, ms", [("16 topics in flight (09:06, load 21-28)", SITE_P95, "darkred"),
                             ("one at a time (08:46, load 15-19)", SITE_P95_ONE_IN_FLIGHT, "orange"),
                             (f"goal: {GOAL_P95_MS:.0f} ms", [(0, GOAL_P95_MS), (max(x for x, _ in SITE_P95), GOAL_P95_MS)],
                              "green")],
                 f"bench/site_scale.py, {SITE_LOAD}")
    to_png({ROOT / "docs" / "scale-cost-per-device.png": cost, ROOT / "docs" / "scale-site-latency.png": site})


if __name__ == "__main__":
    main()
