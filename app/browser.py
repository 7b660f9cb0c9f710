"""What the server (app/web.py) and the pages agree on about a browser: the session token its
cookie carries, the name of its sign-of-life event, and where a login may send it afterwards."""

from __future__ import annotations

from typing import Any

BEAT_EVENT = "commission_beat"  # the socket event of a page's sign of life (dead-man rule)
# run on a page when the dead-man supervisor asks it to beat (true: its session holds something, or its
# connection came back) or to stop (false: it held nothing for a while); pages/frame.py BEAT_JS defines it
BEAT_ASK_JS = "window.commissionBeat && window.commissionBeat.ask && window.commissionBeat.ask(%s)"


def session_token(request: Any) -> str | None:
    """The login token of the browser's signed session cookie (a starlette ``Request``), if any."""
    if request is None or "session" not in request.scope:
        return None
    return request.session.get("auth")


def safe_redirect(target: str) -> str:
    """``target`` when it is a path on this server, else ``/`` (no open redirect)."""
    return target if target.startswith("/") and not target.startswith("//") and "\\" not in target else "/"
