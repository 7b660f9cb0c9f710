"""What every card of the SCU page shares: the unit's live record and declared commands (:class:`ScuView`)
and why controls are off now (:class:`Access`), which the page hands to every card's refresh."""

from __future__ import annotations

from dataclasses import dataclass

from app.message import said
from devices.scu import facts
from pages.command_client import session_role
from pages.device_page import DeviceView


@dataclass(frozen=True, slots=True)
class Access:
    """Why controls are off now (each "" when not): the role, a unit that does not answer, a lost or released
    session, the emergency stop; and who holds control."""

    role: str
    offline: str
    lost: str
    estop: str
    holder: facts.Holder | None
    mine: bool


class ScuView(DeviceView):
    """What every card of one page shares: the device's live record and the declared commands
    (devices/scu/policy.py); its cards are refreshed with what controls may be used now (:class:`Access`)."""

    def __init__(self, name: str):
        super().__init__(name)
        self.viewer = session_role() == "viewer"
        self.scales: tuple[facts.ActuatorScale, ...] = self.fact(facts.P_SCALES, ())  # as at page open
        self.functions: facts.FunctionMap = self.fact(facts.P_FUNCTIONS)

    def access(self) -> Access:
        self.guard.update()
        sess = self.fact(facts.P_SESSION, "closed")
        reason = self.fact(facts.P_SESSION_REASON, "")
        _ = self.lang.gettext
        lost = ""  # a lost or released session: nothing reaches the unit until it is open again
        if sess in ("lost", "released"):
            lost = (_("the remote session is {state}").format(state=self.lang.phrase(sess, "Session"))
                    + (f" ({said(reason, self.lang)})" if reason else "")
                    + (_("; it is reopened with backoff, or press \"Open the remote session\"") if sess == "lost"
                       else _("; press \"Open the remote session\" to drive again")))
        holder = self.fact(facts.P_CONTROL)
        return Access(role=_("a viewer cannot change anything") if self.viewer else "",
                      offline=self.guard.reason,  # writes and motion wait for a unit that answers; the stops never do
                      lost=lost,
                      estop=_("the emergency stop (function 19) is on: release it first") if self.fact(facts.P_ESTOP) else "",
                      holder=holder, mine=holder is not None and holder.session == self.tag)

    def refresh(self) -> None:
        access = self.access()
        for card in self.cards:
            card.refresh(access)


__all__ = ["Access", "ScuView"]
