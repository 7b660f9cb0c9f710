"""Logged-in sessions, one-time login tickets and the login throttle (no UI imports).

A browser is logged in when its signed session cookie carries a token this process
issued at login. The token is made new at every login (a cookie planted before the
login is worth nothing afterwards) and dropped at logout. The account behind a token is
looked up in the account store on every use, so a removed or downgraded account loses
its rights at once.
"""

from __future__ import annotations

import secrets
import time
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass

from app.i18n import N_
from app.message import Message

SESSION_LIFETIME_S = 12 * 3600  # a shift
TICKET_LIFETIME_S = 30.0
MAX_SESSIONS = 1000  # bounded: the oldest sessions go first
FREE_FAILURES = 3  # wrong passwords before the throttle starts
MAX_DELAY_S = 60.0
THROTTLE_ENTRIES = 4096  # bounded: accounts and client addresses tracked
LOGIN_NAME_MAX = 64  # longer typed names are no account (app/users.py): kept to this length in the throttle and the audit
LOGIN_PASSWORD_MAX = 1024  # longer passwords are refused without hashing them
REFUSAL_WINDOW_S = 60.0
REFUSAL_ROWS_PER_CLIENT = 5  # audit rows of refused logins per client address and window; the rest are counted
REFUSAL_ROWS_TOTAL = 60  # and of all addresses together


@dataclass
class _Session:
    user: str
    created: float


class AuthSessions:
    """Tokens of logged-in browsers, and the tickets that turn a login into a fresh session."""

    def __init__(self) -> None:
        self._sessions: OrderedDict[str, _Session] = OrderedDict()
        self._tickets: dict[str, tuple[str, str, float]] = {}

    def issue_ticket(self, user: str, browser: str) -> str:
        """A one-time ticket for ``user``, usable only by the browser (session cookie id) that logged in."""
        now = time.time()
        self._tickets = {k: v for k, v in self._tickets.items() if v[2] > now}
        ticket = secrets.token_urlsafe(24)
        self._tickets[ticket] = (user, browser, now + TICKET_LIFETIME_S)
        return ticket

    def redeem(self, ticket: str, browser: str) -> str | None:
        """The new session token for a valid ticket of this browser (the ticket is used up), else None."""
        entry = self._tickets.pop(ticket, None)
        if entry is None:
            return None
        user, owner, until = entry
        if owner != browser or until < time.time():
            return None
        token = secrets.token_urlsafe(32)
        self._sessions[token] = _Session(user, time.time())
        while len(self._sessions) > MAX_SESSIONS:
            self._sessions.popitem(last=False)
        return token

    def user_of(self, token: str | None) -> str | None:
        if not token:
            return None
        session = self._sessions.get(token)
        if session is None:
            return None
        if time.time() - session.created > SESSION_LIFETIME_S:
            del self._sessions[token]
            return None
        return session.user

    def logout(self, token: str | None) -> None:
        if token:
            self._sessions.pop(token, None)

    def drop_user(self, user: str) -> int:
        """End every session of ``user`` (account removed); returns how many."""
        tokens = [t for t, s in self._sessions.items() if s.user == user]
        for token in tokens:
            del self._sessions[token]
        return len(tokens)


def shown_name(typed: str) -> str:
    """A typed user name as the throttle and the audit log keep it: at most :data:`LOGIN_NAME_MAX`
    characters, a longer one cut with its length noted (no account has such a name)."""
    if len(typed) <= LOGIN_NAME_MAX:
        return typed
    return f"{typed[:LOGIN_NAME_MAX]}... ({len(typed)} characters)"


class RefusalRows:
    """How many audit rows refused logins may write: :data:`REFUSAL_ROWS_PER_CLIENT` per client
    address and :data:`REFUSAL_ROWS_TOTAL` in all per :data:`REFUSAL_WINDOW_S`; the refusals
    beyond are counted, and the next row of that address says how many there were."""

    def __init__(self, window_s: float = REFUSAL_WINDOW_S) -> None:
        self.window_s = window_s
        self._clients: OrderedDict[str, list] = OrderedDict()  # address -> [window start, rows, not written]
        self._total = [0.0, 0]  # window start, rows of all addresses

    def take(self, client: str, now: float | None = None) -> int | None:
        """None: write no row for this refusal (it is counted); else write one, which also
        accounts for the returned number of refusals of this address not written before it."""
        now = time.monotonic() if now is None else now
        entry = self._clients.pop(client, None) or [now, 0, 0]
        self._clients[client] = entry
        while len(self._clients) > THROTTLE_ENTRIES:
            self._clients.popitem(last=False)
        if now - entry[0] >= self.window_s:
            entry[0], entry[1] = now, 0
        if now - self._total[0] >= self.window_s:
            self._total = [now, 0]
        if entry[1] >= REFUSAL_ROWS_PER_CLIENT or self._total[1] >= REFUSAL_ROWS_TOTAL:
            entry[2] += 1
            return None
        entry[1] += 1
        self._total[1] += 1
        skipped, entry[2] = entry[2], 0
        return skipped


class LoginThrottle:
    """Slows down repeated wrong passwords, per account and per client address.

    After :data:`FREE_FAILURES` failures a key must wait 2, 4, 8 ... up to
    :data:`MAX_DELAY_S` seconds after its last failure before its next attempt is checked.
    ``rows`` bounds the audit rows the refusals write. ``clock`` gives the seconds the delays are counted in
    (monotonic: a clock set back never frees an account early).
    """

    def __init__(self, clock: Callable[[], float] = time.monotonic) -> None:
        self.clock = clock
        self._failures: OrderedDict[str, tuple[int, float]] = OrderedDict()
        self.rows = RefusalRows()

    def wait_s(self, *keys: str, now: float | None = None) -> float:
        """Seconds until an attempt for these keys will be checked (0: now)."""
        now = self.clock() if now is None else now
        wait = 0.0
        for key in keys:
            count, last = self._failures.get(key, (0, 0.0))
            if count >= FREE_FAILURES:
                delay = min(MAX_DELAY_S, 2.0 ** (count - FREE_FAILURES + 1))
                wait = max(wait, last + delay - now)
        return max(0.0, wait)

    def failed(self, *keys: str, now: float | None = None) -> int:
        now = self.clock() if now is None else now
        worst = 0
        for key in keys:
            count = self._failures.pop(key, (0, 0.0))[0] + 1
            self._failures[key] = (count, now)
            worst = max(worst, count)
        while len(self._failures) > THROTTLE_ENTRIES:
            self._failures.popitem(last=False)
        return worst

    def succeeded(self, *keys: str) -> None:
        for key in keys:
            self._failures.pop(key, None)


async def check_login(*, throttle: LoginThrottle, users, audit, typed: str, secret: str, address: str, via: str = ""):
    """One login attempt as every face checks it (the web login's rules, shared with the OPC UA server).

    Throttled per account and per client address by ``throttle``; counted as a failure before the
    check (an attempt cut off half-way still counts); the password is hashed in a thread, never on the
    event loop; a name or password too long for an account is refused without hashing; refusals write
    audit rows within ``throttle.rows``. ``via`` names the face in the audit rows (``"opcua"``).
    Returns ``(account or None, words for the user)``: a :class:`~app.message.Message`, worded in the reader's language.
    """
    import asyncio

    account = shown_name(typed)
    keys = (f"user:{account}", f"client:{address}")
    source = f"{via} {address}".strip()

    async def refused(result: str) -> None:
        skipped = throttle.rows.take(address)
        if skipped is None or audit is None:
            return
        if skipped:
            result += f"; {skipped} more refused from this address not written one by one"
        await audit.arecord(user=account or "?", role="", device="", action="login", result=result)

    wait = throttle.wait_s(*keys)
    if wait > 0:
        await refused(f"refused: throttled ({wait:.0f} s) from {source}")
        return None, Message(N_("Too many wrong passwords: try again in {seconds} s."), seconds=round(wait))
    failures = throttle.failed(*keys)
    user = None
    if users is not None and account == typed and len(secret) <= LOGIN_PASSWORD_MAX:
        user = await asyncio.to_thread(users.verify, typed, secret)
    if user is None:
        await refused(f"failed: wrong user name or password from {source} ({failures} in a row)")
        return None, Message(N_("Wrong user name or password"))
    throttle.succeeded(*keys)
    if audit is not None:
        await audit.arecord(user=user.name, role=user.role, device="", action="login", result=f"ok from {source}")
    return user, ""
