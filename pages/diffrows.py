"""The rows of a diff against a device (restore, replacement, project): the columns, the state cell with a
risk drawn in red, and the words of each row's state."""

from __future__ import annotations

from app import backup
from app.i18n import Lang
from app.message import said

WRAP = "white-space: normal; overflow-wrap: break-word"  # long texts wrap inside the screen, never cut off
DIFF_COLUMNS = [
    {"name": "name", "label": "Parameter", "field": "name", "align": "left"},
    {"name": "current", "label": "Device now", "field": "current", "align": "left", "style": WRAP},
    {"name": "backup", "label": "In the backup", "field": "backup", "align": "left", "style": WRAP},
    {"name": "state", "label": "", "field": "state", "align": "left", "style": WRAP + "; min-width: 16rem"},
]
# the risk of a restored value (Param.needs_confirmation) is shown in red with a warning sign
STATE_SLOT = """
    <q-td :props="props" :style="props.col.style">
      <span v-if="props.row.risk" class="text-negative text-weight-medium" data-testid="restore-risk">
        <q-icon name="warning" size="xs" class="q-mr-xs" />{{ props.row.state }}</span>
      <span v-else>{{ props.row.state }}</span>
    </q-td>"""


def count(n: int, noun: str) -> str:
    """"1 parameter", "2 parameters"."""
    return f"{n} {noun}{'' if n == 1 else 's'}"


def row_state(row: backup.DiffRow) -> str:
    if row.error:
        return f"not written: {row.error}"
    if not row.changed:
        return "same"
    return f"differs; risk, needs confirmation: {row.risk}" if row.risk else "differs"


def state_text(row: backup.DiffRow, lang: Lang) -> str:
    """:func:`pages.diffrows.row_state` in ``lang`` (the row's error and risk as the device's record words them)."""
    _ = lang.gettext
    if row.error:
        return _("not written: {error}").format(error=said(row.error, lang))
    if not row.changed:
        return _("same")
    return _("differs; risk, needs confirmation: {risk}").format(risk=said(row.risk, lang)) if row.risk else _("differs")
