"""Freed heap pages go back to the system (app/memory.py)."""

from __future__ import annotations

import asyncio
import subprocess
import sys
import textwrap
import threading

import pytest

from app import memory

pytestmark = pytest.mark.skipif(not memory.available(), reason="needs glibc's malloc_trim")


def test_trim_returns_freed_pages_held_between_live_blocks() -> None:
    # in a fresh interpreter: 60 MB of 1 kB blocks (malloc's, not Python's small-object arenas),
    # every 50th kept, so the freed space lies between live blocks and the heap cannot shrink
    # from its top; the resident size must fall back to near where it started
    script = textwrap.dedent("""
        from app import memory
        def rss():
            for line in open("/proc/self/status"):
                if line.startswith("VmRSS"):
                    return int(line.split()[1]) / 1024
        start = rss()
        blocks = [bytes(1000 + i % 7) for i in range(60000)]
        keep = blocks[::50]
        del blocks
        freed = rss()
        memory.trim()
        print(start, freed, rss())
    """)
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True).stdout
    start, freed, trimmed = map(float, out.split())
    assert freed - start > 40, "the freed blocks stay resident before the trim"
    assert trimmed - start < 15, f"RSS {start:.0f} -> {freed:.0f} -> {trimmed:.0f} MB"


async def test_keep_trimmed_runs_off_the_loop(monkeypatch) -> None:
    calls = []  # whether each trim ran on the event loop's thread
    monkeypatch.setattr(memory, "trim", lambda: calls.append(threading.current_thread() is threading.main_thread()))
    task = asyncio.create_task(memory.keep_trimmed(0.01))
    await asyncio.sleep(0.1)  # ten trim periods of 10 ms
    task.cancel()
    await asyncio.gather(task, return_exceptions=True)
    assert len(calls) >= 3 and not any(calls)
