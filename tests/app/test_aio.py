"""Stopping the program's tasks ends them, also a task whose ``wait_for`` dropped the cancellation (app/aio.py)."""

from __future__ import annotations

import asyncio
import logging
import sys

from app.aio import end_tasks


async def _wakes_and_waits(wake: asyncio.Event, turns: list) -> None:
    """The shape of the MQTT sender: a loop around ``wait_for`` on an event that another task sets."""
    while True:
        try:
            await asyncio.wait_for(wake.wait(), 10)
        except TimeoutError:
            pass
        wake.clear()
        turns.append(1)


async def _cancelled_as_it_wakes(turns: list) -> asyncio.Task:
    wake = asyncio.Event()
    task = asyncio.create_task(_wakes_and_waits(wake, turns), name="sender")
    await asyncio.sleep(0)
    wake.set()
    await asyncio.sleep(0)  # the inner wait has its result: a cancellation now meets wait_for's race
    task.cancel()
    return task


async def test_one_cancel_can_be_dropped_before_python_3_12():
    turns: list = []
    task = await _cancelled_as_it_wakes(turns)
    done, _ = await asyncio.wait({task}, timeout=0.5)
    if sys.version_info < (3, 12):
        assert not done, "wait_for dropped the cancellation (CPython gh-86296): the reason end_tasks cancels again"
    await end_tasks([task], "test")
    assert task.cancelled()


async def test_end_tasks_ends_a_task_that_dropped_its_cancellation():
    turns: list = []
    task = await _cancelled_as_it_wakes(turns)
    assert await end_tasks([task], "test", bound_s=5.0) == []
    assert task.done() and task.cancelled()


async def test_a_task_that_never_ends_is_named_and_left_after_the_bound(caplog):
    caplog.set_level(logging.ERROR, logger="app.aio")
    release = asyncio.Event()

    async def stubborn() -> None:
        while not release.is_set():
            try:
                await asyncio.sleep(10)
            except asyncio.CancelledError:
                continue  # refuses every cancellation

    task = asyncio.create_task(stubborn(), name="stubborn")
    await asyncio.sleep(0)
    left = await end_tasks([task], "test", bound_s=0.5)
    assert left == [task] and not task.done()
    assert any("stubborn" in r.getMessage() and "did not end" in r.getMessage() for r in caplog.records)
    release.set()
    task.cancel()
    await asyncio.wait({task}, timeout=5)
    assert task.done()


async def test_ended_tasks_and_their_errors_are_taken_as_they_are():
    async def fails() -> None:
        raise ValueError("broken")

    done = asyncio.create_task(asyncio.sleep(0))
    failed = asyncio.create_task(fails())
    await asyncio.wait({done, failed})
    assert await end_tasks(iter([done, failed]), "test") == []
