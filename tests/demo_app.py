"""The demo plant in a process of its own for the browser tests: its Modbus line and every other
simulated endpoint on a free port, each of its CAN buses on a virtual channel of its own."""

from __future__ import annotations

import contextlib
import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest
from webutil import demo_plant_text, free_port, running_app

DEMO_CAN_BUSES = range(1, 10)  # the demo's channels demo-can1 ... (more than it has: a new bus is covered)


def private_demo_text(tag: str) -> str:
    """The demo plant file on free ports, its CAN channels named ``<tag>-<random>-<n>``."""
    channel = f"{tag}-{uuid.uuid4().hex[:12]}"
    text = demo_plant_text(free_port())
    assert 'channel = "demo-can1"' in text
    for n in DEMO_CAN_BUSES:
        text = text.replace(f'channel = "demo-can{n}"', f'channel = "{channel}-{n}"')
    return text


@contextlib.contextmanager
def demo_app(folder: Path, tag: str, **env: str) -> Iterator[str]:
    """``python -m app.cli`` on :func:`private_demo_text` in ``folder`` (its data and log there), with ``env``
    set (such as ``COMMISSION_RECORDINGS_DIR``) while it runs; yields its base URL, prints the log's end afterwards."""
    with pytest.MonkeyPatch.context() as mp:
        for key, value in env.items():
            mp.setenv(key, value)
        try:
            with running_app(private_demo_text(tag), folder) as url:
                yield url
        finally:
            log = folder / "app.log"
            if log.exists():
                print(log.read_text(errors="replace")[-3000:])
