"""The HD-Lock page's CAN cards (document section 6): the CAN status and the CAN commands (source, bit rate,
device ID), each sent through the gate."""

from __future__ import annotations


from nicegui import ui

from app import i18n
from app.i18n import N_
from app.message import said
from devices.hdlock import codec
from devices.hdlock.adapter import (
    P_FWU,
    P_STATUS_FRAME,
)
from devices.hdlock.params import PARAMS
from pages.cards import DeviceCard, titled_card
from pages.command_client import confirm, WriteGuard
from pages.command_client import refuse, run_command


class CanStatusCard(DeviceCard):
    """What the periodic status frame (section 6.5.1) and FWU status (6.5.2) say, as the adapter publishes it."""

    def build(self) -> None:
        _ = self.view.lang.gettext
        with titled_card(_("CAN status frame (every 1000 ms)")):
            self.text = ui.label(_("no status frame yet")).classes("text-body2 mono")
            self.fwu = ui.label().classes("text-body2 text-warning")

    def refresh(self) -> None:
        if self.unchanged(self.view.inputs((P_STATUS_FRAME, P_FWU)), lambda: None):
            return
        status = self.view.state.live(P_STATUS_FRAME)
        if status is not None:
            self.text.set_text(said(status.shown, self.view.lang))
        fwu = self.view.state.live(P_FWU)
        self.fwu.set_text("" if fwu is None or fwu.value is None else said(fwu.shown, self.view.lang))


def can_commands_card(name: str, state, guard: WriteGuard, lang=None) -> None:
    """Commands through 0x700 and Set Device Address through 0x701 (section 6.6)."""
    _ = (lang or i18n.get("en")).gettext
    sources = PARAMS.by_name["LockRequestSource"].enum
    with titled_card(_("CAN commands (0x700, 0x701)")):
        broadcast = ui.checkbox(_("Send to all locks on this bus (broadcast, device ID 0)"))
        with ui.row().classes("items-center"):
            source = ui.select({k: f"{v} (0x{k:02X})" for k, v in sources.items()}, label="LockRequestSource").props("dense outlined options-dense").classes("w-72")
            guard.add(ui.button(_("Set"), on_click=lambda: _send_source(name, source, broadcast.value)).props("dense"))
        with ui.row().classes("items-center"):
            rate = ui.select(
                {k: f"{r // 1000 if r % 1000 == 0 else r / 1000:g} kbit/s" + (f" ({length})" if length else "") for k, (r, length) in codec.CAN_BITRATES.items()},
                label=_("CAN bit rate"),
            ).props("dense outlined options-dense").classes("w-72")
            guard.add(ui.button(_("Set"), on_click=lambda: _send_bitrate(name, rate, broadcast.value)).props("dense color=negative"))
        ui.separator()
        ui.label(_("Set Device Address (0x701)")).classes("text-body2 text-weight-medium")
        ui.label(
            _("IDs above 0x7FF are extended (29-bit) automatically; tick Extended to use an extended ID up to 0x7FF "
              "(the request then carries 0x80000000).")
        ).classes("text-caption text-grey-8")
        with ui.row().classes("items-center"):
            new_id = ui.input(_("New device ID (dec or 0x hex)")).props("dense outlined").classes("w-56")
            extended = ui.checkbox(_("Extended"))
            guard.add(ui.button(_("Send"), on_click=lambda: _send_device_id(name, new_id, extended.value)).props("dense"))


async def _send_source(name: str, field, broadcast: bool) -> None:
    value = field.value
    if value is None:
        field.error = i18n.client_language().gettext("choose a LockRequestSource first")
        return
    _ = i18n.client_language().gettext
    field.error = None
    label = PARAMS.by_name["LockRequestSource"].enum[value]
    # 0x80-0x87 (the door ignored) and a broadcast are risks the HD-Lock policy names: the gate asks them
    await run_command(name, "cmdSetLockRequestSource", args={"value": value, "broadcast": broadcast},
                      success=(_("LockRequestSource {label} sent to all locks") if broadcast
                               else _("LockRequestSource {label} sent and read back from holding 4")).format(label=label))


async def _send_bitrate(name: str, field, broadcast: bool) -> None:
    code = field.value
    if code is None:
        field.error = i18n.client_language().gettext("choose a bit rate first")
        return
    _ = i18n.client_language().gettext
    field.error = None
    rate = codec.CAN_BITRATES[code][0]
    who = _("Every lock on this bus") if broadcast else _("The lock")
    if not await confirm(
        _("Switch to {rate} bit/s?").format(rate=rate),
        _("{who} leaves this bus at once and is unreachable until the bus itself is switched to {rate} bit/s (change "
          "bitrate in the plant file and restart). Send Save-Settings first if other changes should be kept.").format(
            who=who, rate=rate),
        ok=_("Switch bit rate"),
    ):
        return
    await run_command(name, "cmdSetCANbaudrate", args={"code": code, "broadcast": broadcast}, confirmed=True,
                      success=_("bit rate {rate} bit/s sent").format(rate=rate))  # the question above names the risk


async def _send_device_id(name: str, field, extended: bool) -> None:
    """Set Device Address (section 6.6): a wrong entry stays in the field, marked, and is audited; nothing is sent."""
    text = field.value
    try:
        value = int(str(text).strip(), 0)
        new = codec.DeviceId.make(value, extended or None)
        reason = N_("0 is the broadcast address") if value == 0 else None
    except (ValueError, codec.CodecError) as exc:
        reason = str(exc) if isinstance(exc, codec.CodecError) else N_("a number, e.g. 11 or 0x1A2B")
    field.error = None if reason is None else i18n.client_language().gettext(reason)  # the audit row: English
    if reason is not None:
        await refuse(name, "Set Device Address", f"{text!r}: {reason}", parameter="DeviceId", new=text)
        return
    # refused when another participant uses the ID (section 6.2 b), asked first otherwise: the HD-Lock policy
    ok, heard = await run_command(name, "Set Device Address", args={"new_value": new.value, "extended": new.extended})
    if ok:
        if heard:
            ui.notify(i18n.client_language().gettext("The lock answers under {id} now").format(id=new), type="positive")
        else:
            ui.notify(i18n.client_language().gettext("No frame under the new ID: the lock may have kept its old ID"),
                      type="warning")
