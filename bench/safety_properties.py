"""The safety invariants over many random fault sequences, per device family (issue 40).

Each family's stateful property test (``tests/safety/test_safety_<family>.py``) declares its hypothesis
``RuleBasedStateMachine`` in ``SAFETY_MACHINES`` (and plain ``@given`` properties in
``SAFETY_PROPERTIES``). The suite runs a bounded, derandomised number of sequences; this runs at
least ``--sequences`` (1,000) per family with a random seed, so each run explores new sequences, and
prints per family the sequences run, the steps taken, the time, and the failures with the shrunk
sequence that shows each.

Last line: ``safety_sequences_failed: N`` (goal: 0).

Usage: ``python bench/safety_properties.py [--sequences 1000] [--steps 60] [--seed S] [--family scu]``
"""

from __future__ import annotations

import argparse
import importlib
import random
import sys
import time
import traceback
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path[:0] = [str(ROOT), str(ROOT / "tests"), str(ROOT / "tests" / "safety")]

FAMILIES = ("hdlock", "m3io", "scu", "mo64", "electrak")


def collect(only: str | None) -> dict[str, list[tuple[str, object]]]:
    """family -> [(name, machine class or @given test)] from the tests' declarations."""
    found: dict[str, list[tuple[str, object]]] = {}
    for family in FAMILIES:
        if only and family != only:
            continue
        try:
            module = importlib.import_module(f"test_safety_{family}")
        except ImportError as exc:
            print(f"{family}: no property tests ({exc})")
            continue
        for key, machine in getattr(module, "SAFETY_MACHINES", {}).items():
            found.setdefault(key, []).append((machine.__name__, machine))
        for key, tests in getattr(module, "SAFETY_PROPERTIES", {}).items():
            for test in tests:
                found.setdefault(key, []).append((test.__name__, test))
    return found


def run_one(name: str, target, sequences: int, steps: int, seed: int) -> tuple[int, str]:
    """Run ``target`` for ``sequences`` examples; (examples run, failure text or "")."""
    from hypothesis import HealthCheck, settings
    from hypothesis.stateful import RuleBasedStateMachine, run_state_machine_as_test

    count = {"n": 0}
    config = settings(max_examples=sequences, stateful_step_count=steps, deadline=None, database=None,
                      suppress_health_check=list(HealthCheck), derandomize=False)
    try:
        if isinstance(target, type) and issubclass(target, RuleBasedStateMachine):
            class Counted(target):  # type: ignore[misc, valid-type]
                def teardown(self):
                    count["n"] += 1
                    super().teardown()

            Counted.__name__ = target.__name__
            run_state_machine_as_test(Counted, settings=config)
        else:
            # a @given property: hypothesis's own entry for outside fuzzers, one example per random buffer
            rng = random.Random(seed)
            fuzz = target.hypothesis.fuzz_one_input
            for _ in range(sequences):
                fuzz(rng.randbytes(rng.choice((64, 256, 1024, 4096))))
                count["n"] += 1
        return count["n"], ""
    except Exception:  # noqa: BLE001 - a failing property is the result this reports
        return count["n"], traceback.format_exc(limit=3)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sequences", type=int, default=1000, help="random sequences per family (at least)")
    parser.add_argument("--steps", type=int, default=60, help="steps per sequence at most")
    parser.add_argument("--seed", type=int, default=None)
    parser.add_argument("--family", choices=FAMILIES, default=None)
    args = parser.parse_args()
    seed = args.seed if args.seed is not None else random.SystemRandom().randrange(2 ** 32)
    random.seed(seed)
    print(f"seed {seed}; at least {args.sequences} sequences per family, up to {args.steps} steps each")
    failed = 0
    total = 0
    for family, targets in sorted(collect(args.family).items()):
        per_family = 0
        started = time.perf_counter()
        for name, target in targets:
            n, failure = run_one(name, target, args.sequences, args.steps, seed)
            per_family += n
            if failure:
                failed += 1
                print(f"{family}: {name} FAILED after {n} sequences:\n{failure}")
        seconds = time.perf_counter() - started
        total += per_family
        print(f"{family}: {per_family} sequences in {seconds:.1f} s ({len(targets)} machines/properties)")
        print(f"safety_sequences_{family}: {per_family}")
    print(f"safety_sequences_total: {total}")
    print(f"safety_sequences_failed: {failed}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
