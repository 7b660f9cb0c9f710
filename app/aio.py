"""Ending the program's own asyncio tasks, bounded.

Before Python 3.12, ``asyncio.wait_for`` returns its inner result and drops a cancellation that arrives in the
same loop turn as that result (CPython gh-86296). A task in a loop around ``wait_for`` can so live on after one
``cancel()``, and a stop that awaits it waits for ever (an MQTT stop hung like that while its broker connection
was being taken over). :func:`end_tasks` cancels again until every task has ended, within a bound.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Iterable

log = logging.getLogger(__name__)

RECANCEL_S = 0.2  # how long a cancelled task is given before it is cancelled again


async def end_tasks(tasks: Iterable[asyncio.Task], what: str, bound_s: float = 5.0) -> list[asyncio.Task]:
    """Cancel ``tasks`` and wait until they have ended, cancelling again those that swallowed a cancellation;
    after ``bound_s`` the ones still running are logged (``what`` names them) and returned, never awaited."""
    tasks = list(tasks)
    pending = {task for task in tasks if not task.done()}
    loop = asyncio.get_running_loop()
    deadline = loop.time() + bound_s
    while pending:
        for task in pending:
            task.cancel()
        left = deadline - loop.time()
        if left <= 0:
            names = ", ".join(sorted(task.get_name() for task in pending))
            log.error("%s: %d task(s) did not end within %.0f s of being cancelled: %s", what, len(pending), bound_s, names)
            return sorted(pending, key=lambda task: task.get_name())
        _, pending = await asyncio.wait(pending, timeout=min(RECANCEL_S, left))
    for task in tasks:
        if task.done() and not task.cancelled() and task.exception() is not None:
            log.debug("%s: task %s ended with %r", what, task.get_name(), task.exception())
    return []
