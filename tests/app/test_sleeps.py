"""Every constant sleep in the suite says why it is a real delay (tools/sleeps.py lists them)."""

from tools import sleeps


def test_every_constant_sleep_names_its_reason():
    unexplained = [f"{s.path}:{s.line}: {s.call}" for s in sleeps.all_sleeps() if s.kind == "UNEXPLAINED"]
    assert unexplained == [], "wait on a condition with eventually(), or say why the delay is real:\n" + "\n".join(unexplained)


def test_the_scan_tells_a_poll_from_a_delay(tmp_path, monkeypatch):
    monkeypatch.setattr(sleeps, "ROOT", tmp_path)
    (tmp_path / "t.py").write_text(
        "import asyncio, time\n"
        "async def f():\n"
        "    await asyncio.sleep(0)\n"
        "    while True:\n"
        "        await asyncio.sleep(0.1)\n"
        "    await asyncio.sleep(0.3)  # three status periods\n"
        "    time.sleep(1)\n"
        "def g(page):\n"
        "    page.wait_for_timeout(1500)\n"
        "    page.wait_for_timeout(700)  # two refresh periods: a paused list must not move\n"
    )
    kinds = [(s.line, s.kind) for s in sleeps.scan(tmp_path / "t.py")]
    assert kinds == [(3, "yield"), (5, "poll"), (6, "delay"), (7, "UNEXPLAINED"), (9, "UNEXPLAINED"), (10, "delay")]
