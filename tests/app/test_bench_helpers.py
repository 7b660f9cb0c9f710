"""The benchmarks run after `pip install -e .` alone: no pytest, nothing from tests/."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
BENCH = ROOT / "bench"
sys.path.insert(0, str(BENCH))

import liveapp  # noqa: E402

# runs a benchmark's --help with pytest and the test helpers made unimportable
WITHOUT_TESTS = """
import runpy, sys
for name in ("pytest", "conftest", "webutil", "_pytest"):
    sys.modules[name] = None
sys.argv = [sys.argv[1], "--help"]
try:
    runpy.run_path(sys.argv[0], run_name="__main__")
except SystemExit as exc:
    sys.exit(exc.code)
"""


@pytest.mark.parametrize("name", ["browser_load.py", "browser_latency.py", "idle_cost.py", "soak.py",
                                  "page_cost_devices.py", "page_cost_motion.py"])
def test_benchmark_starts_without_pytest_or_the_tests_folder(name, tmp_path):
    result = subprocess.run([sys.executable, "-c", WITHOUT_TESTS, str(BENCH / name)], cwd=tmp_path,
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr[-2000:]
    assert "usage:" in result.stdout


def test_demo_plant_for_a_benchmark_uses_no_fixed_port():
    text = liveapp.demo_plant_text(liveapp.free_port())
    for fixed in ("127.0.0.1:5020", "127.0.0.1:5030", "127.0.0.1:5041", "port = 5040"):
        assert fixed not in text


def test_split_plant_puts_every_can_bus_on_a_multicast_group_of_its_own():
    from app.plant import parse_plant

    plant = parse_plant(liveapp.across_processes(liveapp.demo_plant_text()))
    can = [b for b in plant.buses.values() if b.type == "can"]
    assert can and all(b.options["interface"] == "udp_multicast" for b in can)
    assert len({b.options["channel"] for b in can}) == len(can)


def test_wait_http_takes_the_statuses_it_is_told():
    """running_app waits on /api/devices, where a login refuses with 401: that is an answer too."""
    import http.server
    import threading

    class Refuse(http.server.BaseHTTPRequestHandler):
        def do_GET(self):  # noqa: N802 - the standard library's name
            self.send_response(401)
            self.end_headers()

        def log_message(self, *args):
            pass

    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Refuse)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    try:
        url = f"http://127.0.0.1:{server.server_address[1]}/api/devices"
        liveapp.wait_http(url, accept=(200, 401), timeout=5)
        with pytest.raises(TimeoutError):
            liveapp.wait_http(url, timeout=0.5)
    finally:
        server.shutdown()
        server.server_close()
