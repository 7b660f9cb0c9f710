"""One actuator of the SCU twin (devices/scu/sim.py): position in encoder counts between its end positions, motion,
currents and counters, and its status words (document 002, table 6)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from devices.scu import params
from devices.scu.codec import Motion

DEFAULT_IN_COUNTS = 0
DEFAULT_OUT_COUNTS = 3000
DEFAULT_COUNTS_PER_MM = 12.5
IDLE_CURRENT_A = 0.0


@dataclass
class ActuatorTwin:
    """One actuator: position in encoder counts between its end positions, motion, currents, counters."""

    number: int
    in_counts: int = DEFAULT_IN_COUNTS
    out_counts: int = DEFAULT_OUT_COUNTS
    counts_per_mm: float = DEFAULT_COUNTS_PER_MM
    position: float = 0.0
    speed: float = 0.0  # counts/s, >= 0
    direction: int = 0  # +1 out, -1 in, 0 still
    target: float | None = None
    soft: bool = True
    function: int | None = None  # fnc_ID driving it
    motion: Motion = Motion.NONE
    load_a: float = 0.0
    current_a: float = 0.0
    max_current_a: float = 0.0
    relay_in: int = 0
    relay_out: int = 0
    cumulated_stroke: float = 0.0
    errors: int = 0  # linear actuator errors (0x0081.. low 2 bytes)
    peak_current_count: int = 0
    short_circuit_count: int = 0
    user_positions: dict[str, int] = field(default_factory=dict)

    @property
    def moving(self) -> bool:
        return self.target is not None

    @property
    def at_in(self) -> bool:
        return self.position <= self.in_counts

    @property
    def at_out(self) -> bool:
        return self.position >= self.out_counts

    @property
    def status_1(self) -> int:
        """Actuator Status 1 (0x0171.., table 6)."""
        bits = 1 | 1 << 7  # present, stroke recorded
        if self.at_in or self.at_out:
            bits |= 1 << 1  # signal limit_in_out
        if self.moving:
            bits |= 1 << 4
        if self.at_in:
            bits |= 1 << 5
        if self.at_out:
            bits |= 1 << 6
        return bits

    @property
    def status_2(self) -> int:
        """Actuator status 2 (0x00E1..): initialised, enable flags for the directions still open."""
        return 1 | (0 if self.at_in else 1 << 1) | (0 if self.at_out else 1 << 2)

    def stop(self) -> None:
        self.target = None
        self.direction = 0
        self.speed = 0.0
        self.function = None
        self.current_a = IDLE_CURRENT_A


def actuator_configs(option: Any) -> list[dict]:
    if isinstance(option, int) and not isinstance(option, bool):
        if not 1 <= option <= params.ACTUATORS:
            raise ValueError(f"an SCU drives 1 .. {params.ACTUATORS} actuators, not {option}")
        return [{} for _ in range(option)]
    if isinstance(option, (list, tuple)) and 1 <= len(option) <= params.ACTUATORS:
        return [dict(o or {}) for o in option]
    raise ValueError(f"actuators must be 1 .. {params.ACTUATORS} or a list of up to {params.ACTUATORS} tables")
