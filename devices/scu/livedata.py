"""The SCU's live points: the values of RG and RC answers published as one change of the record each
(document 002, tables 6 and 10). What the adapter reads, this part words and publishes."""

from __future__ import annotations

import functools
import time
from typing import TYPE_CHECKING, Any

from devices import values as v
from devices.live import Point
from devices.message import Message, N_
from devices.scu import codec
from devices.scu import params as p
from devices.scu.facts import P_RC_GAP, P_RC_PERIOD, chart_points, point_collector, value_text

if TYPE_CHECKING:
    from devices.scu.adapter import ScuAdapter

ROTATING_IDS = (0x00F0, 0x0164, 0x0040, 0x0020, 0x0110, 0x0120, 0x0130, 0x0140, 0x0150, 0x0162, 0x0165, 0x0166,
                0x0030, 0x00D2, 0x00D3, 0x00D4, 0x00D5, 0x3010, 0x3020, 0x0001, 0x0002)  # settings (drift), identity
ERROR_BIT_GROUPS = ((0x00D1, "Error code"), (0x00D2, "Error history 1"), (0x00D3, "Error history 2"),
                    (0x00D4, "Error history 3"), (0x00D5, "Error history 4"))


class ScuLiveData:
    """The live points of one SCU adapter."""

    def __init__(self, adapter: ScuAdapter):
        self.adapter = adapter
        self.state = adapter.state
        self.read_at: dict[int, float] = {}  # RG data ID -> when it was last read (one entry per ID read)
        self.remote_timeout_seen = False
        self.memo: tuple | None = None  # (cyclic object, RC answer data, scales), its values and point contents
        self.rotate = 0  # the turn of the data IDs read one a poll (ROTATING_IDS)
        self.rg_on_loop: list[int] = []  # reads the line's thread could not make well: made by the next poll instead

    def publish_read(self, read_id: int, answer: codec.Answer) -> None:
        """An RG answer of a data ID read in turn with the others: it ages by its own period (measured between two
        reads; before the second one, the time one turn of them takes)."""
        now = time.monotonic()
        last = self.read_at.get(read_id)
        self.read_at[read_id] = now
        try:
            value = p.rg_value(read_id, answer)
        except (v.DecodeError, ValueError) as exc:
            self.state.error(f"RG 0x{read_id:04X}: {exc}", log=False)
            return
        self.publish_ids({read_id: value}, every=self.rotation_s if last is None else now - last)

    @property
    def rotation_s(self) -> float:
        """How long one turn of the data IDs read in turn takes (one a poll)."""
        return len(ROTATING_IDS) * float(self.adapter.line.options.get("poll_period", 0.5) or 0.5)

    def publish_period(self) -> None:
        gaps = self.adapter.rc.gaps()
        if gaps:
            mean, longest = round(sum(gaps) / len(gaps) * 1000, 1), round(max(gaps) * 1000, 1)
            self.state.publish(P_RC_PERIOD, mean, "ms", text=f"mean {mean:g} ms, longest gap {longest:g} ms")
            self.state.publish(P_RC_GAP, longest, "ms")

    def publish_ids(self, values: dict[int, Any], every: float | None = None) -> None:
        """The points of an answer's values, as one change of the record (:meth:`DeviceState.publish_telegram`)."""
        now = time.time()
        points: dict[str, Point] = {}
        self.collect_ids(values, every, now, points)
        self.publish_points(values, points, now)

    def collect_ids(self, values: dict[int, Any], every: float | None, now: float, points: dict[str, Point]) -> None:
        pub = point_collector(points, now, every)
        for data_id, value in values.items():
            members = value if isinstance(value, dict) else {data_id: value}
            for member, x in members.items():
                self.publish_one(member, x, now, every, pub)

    def publish_points(self, values: dict[int, Any], points: dict[str, Point], now: float) -> None:
        sample = None
        if 0x0010 in values or any(0x0011 <= i <= 0x0016 for i in values):
            names = chart_points(self.adapter.scales)
            if any(n in points or n in self.state.points for n in names):
                sample = functools.partial(self.state.sample_of, names)
        self.state.publish_telegram(now, points, None, sample)

    def publish_cyclic_data(self, cyclic: p.CyclicDefinition, data: bytes) -> None:
        """The data of an RC answer (every 200 ms): its points as one change of the record. The same bytes as the
        answer before (a unit at rest) are not decoded and worded again, only their time is new."""
        now = time.time()
        key = (cyclic, data, tuple(self.adapter.scales))
        memo = self.memo
        if memo is not None and memo[0] == key:
            _key, values, contents = memo
            for data_id, value in values.items():  # what the words mean besides points: the remote timeout bit
                members = value if isinstance(value, dict) else {data_id: value}
                if 0x00D1 in members:
                    self.note_remote_timeout(members[0x00D1])
            make = Point._make
            points = {name: make((c[0], c[1], now, c[2], c[3], c[4], c[5])) for name, c in contents.items()}
        else:
            values = cyclic.decode_read(data)
            points = {}
            self.collect_ids(values, None, now, points)
            self.memo = (key, values, {name: (pt.value, pt.unit, pt.raw, pt.text, pt.periodic, pt.every)
                                               for name, pt in points.items()})
        self.publish_points(values, points, now)

    def note_remote_timeout(self, x: Any) -> None:
        """Error bit 22 (remote communication timeout) of 0x00D1 newly set while the session is open: it is lost."""
        timeout = bool(int(x) & codec.REMOTE_TIMEOUT_MASK)
        if timeout and not self.remote_timeout_seen and self.adapter.session == "open" and self.adapter.rc.times and len(self.adapter.rc.times) > 2:
            self.adapter.lost(Message(N_("error bit 22 (remote communication timeout) is set")))
        self.remote_timeout_seen = timeout

    def publish_one(self, data_id: int, x: Any, now: float, every: float | None = None, pub=None) -> None:
        if pub is None:
            pub = self.state.publish if every is None else functools.partial(self.state.publish, every=every)
        entry = p.DIRECTORY.get(data_id)
        if entry is None:
            return
        self.adapter.settings.note(data_id, x, now)
        n = entry.actuator
        if n is not None and n > len(self.adapter.scales):
            return
        group = entry.group
        if group == 0x0010:
            scale = self.adapter.scales[n - 1]
            mm = scale.mm(x)
            pub(f"A{n} position", x, "counts", raw=x, time=now, text=f"{x} counts" + (f" = {mm:g} mm" if mm is not None else ""))
            if mm is not None:
                pub(f"A{n} position mm", mm, "mm", raw=x, time=now)
        elif group in (0x0170, 0x00E0):
            label = "status 1" if group == 0x0170 else "status 2"
            pub(f"A{n} {label}", int(x), raw=int(x), time=now, text=value_text(data_id, x))
            for key, bit in x.fields.items():
                pub(f"A{n} {key}", bool(bit), raw=int(bool(bit)), time=now)
        elif group == 0x00A0:
            pub(f"A{n} current", round(x, 1), "A", raw=round(x * 10), time=now)
        elif group == 0x00F0:
            pub(f"A{n} speed", x, "% or counts/s", raw=x, time=now)
        elif group == 0x0030:
            pub(f"Analogue input {data_id - 0x0030}", round(x, 2), "V", time=now)
        elif data_id in dict(ERROR_BIT_GROUPS):
            title = dict(ERROR_BIT_GROUPS)[data_id]
            pub(title, int(x), raw=int(x), time=now, text=codec.error_text(int(x)))  # the page's words (table 10)
            if data_id == 0x00D1:
                for b in codec.ERROR_BITS.values():
                    pub(f"Error bit {b.bit}", bool(int(x) & b.mask), time=now, text=b.cause)
                self.note_remote_timeout(x)
        elif data_id == 0x0164:
            pub("Battery voltage", round(x, 1), "V", raw=round(x * 10), time=now)
        elif data_id in (0x0100, 0x0020, 0x0110, 0x0120, 0x0130, 0x0140, 0x0150, 0x0162):
            pub(entry.name, int(x), raw=int(x), time=now, text=value_text(data_id, x))
            if data_id in (0x0100, 0x0110, 0x0140, 0x0150):
                for key, bit in x.fields.items():
                    pub(key.replace("_", " ").capitalize(), bool(bit), time=now)
        elif data_id in (0x0001, 0x0002):
            pub(entry.name, str(x), periodic=False)
        elif data_id == 0x0040:
            pub("Keys", int(x), raw=int(x), time=now, text=f"0x{int(x):08X}" + (
                " (keys pressed: bits " + ", ".join(str(b) for b in range(32) if int(x) >> b & 1) + ")" if x else " (none)"))
        elif data_id in (0x0165, 0x0166):
            pub(entry.name, int(x), time=now)
