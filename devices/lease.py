"""A lease: what keeps a device moving must expire by itself when the program stalls.

The event loop's dead-man supervisor renews the lease of every running motion or mains
output (app.worker, every 50 ms while the controlling browser confirms it is alive); the
sender of the cyclic telegram (python-can's cyclic task thread, a serial line's own thread)
asks :meth:`Lease.valid` before every period and, once the lease has lapsed, sends the stop
form by itself. A lapse latches: renewing a lapsed lease fails until the loop has seen the
lapse and granted a new one (:meth:`Lease.grant`), so a program that wakes up from a stall
never restarts motion by itself.

Thread-safe, on the monotonic clock; no I/O, no asyncio.
"""

from __future__ import annotations

import threading
import time
import weakref

LEASE_S = 0.35  # valid this long after a renewal: with a 100 ms period the stop form leaves <= 0.35 + 0.1 s after the last renewal
RENEW_S = 0.05  # the supervisor renews this often (app.worker.SUPERVISE_PERIOD_S)

_GRANTED: "weakref.WeakSet[Lease]" = weakref.WeakSet()  # leases granted and not revoked: something runs under them


def any_granted() -> bool:
    """Whether some motion or mains output runs under a lease now (granted and not revoked, lapsed or not):
    what may not wait for the interpreter (e.g. a full collection of the cyclic garbage collector, see
    app.runtime.FullCollections) is better put off meanwhile."""
    return any(lease.granted for lease in list(_GRANTED))


class Lease:
    """A permission to keep something running that lapses unless renewed in time.

    :param valid_s: how long a grant or a renewal keeps the lease valid
    """

    def __init__(self, valid_s: float = LEASE_S):
        self.valid_s = valid_s
        self._lock = threading.Lock()
        self._until = 0.0  # monotonic time the lease runs out; 0: not granted
        self._lapsed_at: float | None = None  # when a granted lease was found lapsed (latched)
        self._renewed_at: float | None = None

    def grant(self, now: float | None = None) -> None:
        """Start (or restart) the lease: valid for ``valid_s`` from now; clears a latched lapse."""
        now = time.monotonic() if now is None else now
        with self._lock:
            self._until = now + self.valid_s
            self._lapsed_at = None
            self._renewed_at = now
        _GRANTED.add(self)

    def renew(self, now: float | None = None) -> bool:
        """Extend a granted lease; False (and nothing extended) when it is not granted or has lapsed."""
        now = time.monotonic() if now is None else now
        with self._lock:
            if self._until == 0.0 or self._lapsed_at is not None:
                return False
            if now > self._until:  # lapsed before this renewal came: latch it
                self._lapsed_at = self._until
                return False
            self._until = now + self.valid_s
            self._renewed_at = now
            return True

    def revoke(self) -> None:
        """End the lease without a lapse (the motion was stopped on purpose)."""
        with self._lock:
            self._until = 0.0
            self._lapsed_at = None
        _GRANTED.discard(self)

    def valid(self, now: float | None = None) -> bool:
        """Whether the lease holds now; a granted lease found past its time is latched as lapsed."""
        now = time.monotonic() if now is None else now
        with self._lock:
            if self._until == 0.0 or self._lapsed_at is not None:
                return False
            if now > self._until:
                self._lapsed_at = self._until
                return False
            return True

    @property
    def granted(self) -> bool:
        with self._lock:
            return self._until != 0.0

    @property
    def lapsed_at(self) -> float | None:
        """Monotonic time the lease ran out, once a lapse was noticed; None otherwise."""
        with self._lock:
            return self._lapsed_at

    @property
    def renewed_at(self) -> float | None:
        with self._lock:
            return self._renewed_at
