"""The audit log under attack from the login page, and its CSV export (issue 33, item 5)."""

from __future__ import annotations

import csv
import io

import pytest
from conftest import wait_for
from test_auth import login, secured_app

from app.audit import AuditEntry, to_csv
from app.auth import LOGIN_NAME_MAX, REFUSAL_ROWS_PER_CLIENT, RefusalRows

pytestmark = pytest.mark.timeout(90)


async def test_a_login_flood_with_huge_names_writes_few_short_rows(tmp_path):
    async with secured_app(tmp_path) as (user, runtime):
        huge = "x" * 65536
        runtime.login_throttle.clock = lambda: 1000.0  # the flood comes faster than the throttle's delays, however loaded the machine
        attempts = 3 * REFUSAL_ROWS_PER_CLIENT
        for n in range(attempts):
            await login(user, huge + str(n), "wrong guess!", succeeds=False)
            await user.should_see("Wrong user name or password" if n < 3 else "Too many wrong passwords", retries=50)
        # the attempts are all handled (the last one's answer is on the page; its row is written in the audit's
        # own thread, maybe just after); rows stay bounded
        def login_rows() -> list:
            return [e for e in runtime.audit.query() if e.action == "login"]

        await wait_for(lambda: len(login_rows()) >= REFUSAL_ROWS_PER_CLIENT)
        rows = login_rows()
        assert len(rows) == REFUSAL_ROWS_PER_CLIENT, [r.result for r in rows]
        assert all(len(r.user) <= LOGIN_NAME_MAX + 30 for r in rows), max(len(r.user) for r in rows)
        assert "(65537 characters)" in rows[-1].user
        assert runtime.audit.path.stat().st_size < 1_000_000
        # the next window's first row counts what was not written one by one
        runtime.login_throttle.rows.window_s = 0.0
        await login(user, "anna", "wrong guess!", succeeds=False)
        assert await wait_for(lambda: len(login_rows()) == len(rows) + 1)
        newest = runtime.audit.query(limit=1)[0]
        assert f"{attempts - REFUSAL_ROWS_PER_CLIENT} more refused from this address" in newest.result, newest.result


def test_refusal_rows_per_client_and_in_all():
    rows = RefusalRows(window_s=60)
    assert [rows.take("a", now=t) for t in range(7)] == [0, 0, 0, 0, 0, None, None]
    assert rows.take("b", now=7) == 0  # another address has rows of its own
    assert rows.take("a", now=61) == 2  # a new window: its first row counts the two not written
    many = RefusalRows(window_s=60)
    written = sum(many.take(f"10.0.{n // 256}.{n % 256}", now=1) is not None for n in range(1000))
    assert written == 60  # a thousand addresses together write no more than the total


def test_csv_cells_never_start_a_formula():
    entry = AuditEntry(1, 0.0, "=HYPERLINK(\"http://x\")", "", "", "login", "+cmd", "-30", "@SUM(A1)", "-2+3 refused")
    cells = next(csv.reader(io.StringIO(to_csv([entry]).splitlines()[1])))
    assert cells[1] == "'=HYPERLINK(\"http://x\")"
    assert cells[5] == "'+cmd" and cells[7] == "'@SUM(A1)" and cells[8] == "'-2+3 refused"
    assert cells[6] == "-30"  # a plain number stays a number
