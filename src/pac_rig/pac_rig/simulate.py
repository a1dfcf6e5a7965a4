"""Offline closed-loop simulation to a rosbag2/MCAP bag: ``ros2 run pac_rig simulate``."""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pac_common import messages
from pac_common.parameters import ParameterError, ParameterSet

from .bag import BagWriter
from .cli import OverrideError, add_override_arguments, overrides_from_args
from .closed_loop import DivergenceError, Scenario, TickRecord, run


def scenario_sets(s: Scenario) -> dict[str, ParameterSet]:
    return {f.name: getattr(s, f.name) for f in dataclasses.fields(s)}


def scenario_to_flat(s: Scenario) -> dict[str, Any]:
    flat: dict[str, Any] = {}
    for pset in scenario_sets(s).values():
        flat.update(pset.as_dict())
    return flat


def scenario_from_flat(values: dict[str, Any], base: Scenario | None = None) -> Scenario:
    """A scenario with ``values`` (flat parameter names) over ``base``; unknown names are errors."""
    base = base or Scenario()
    known: set[str] = set()
    updated = {}
    for name, pset in scenario_sets(base).items():
        names = {spec.name for spec in pset.specs()}
        known |= names
        mine = {k: v for k, v in values.items() if k in names}
        updated[name] = dataclasses.replace(pset, **mine) if mine else pset
    unknown = sorted(set(values) - known)
    if unknown:
        raise ParameterError(unknown[0], values[unknown[0]], "a known parameter name (see --list)")
    return Scenario(**updated)


@dataclass(frozen=True)
class RunResult:
    bag_path: Path
    ticks: int
    diverged: str | None  # reason, when the run stopped at divergence
    wall_seconds: float
    simulated_seconds: float


def simulate_to_bag(
    scenario: Scenario,
    bag_path: Path | str,
    label: str = "",
    on_record: Callable[[TickRecord], None] | None = None,
) -> RunResult:
    """Run ``scenario`` offline and record the four topics; log time = simulated time.

    ``on_record`` sees every tick's record too (e.g. to compute measures without reading the bag).
    """
    rate = scenario.loop.rate_hz
    delay = scenario.loop.command_delay_ticks
    start = time.perf_counter()
    ticks = 0
    diverged = None
    with BagWriter(
        bag_path, {"source": "offline", "label": label, "parameters": scenario_to_flat(scenario)}
    ) as bag:
        try:
            for rec in run(scenario):
                k = rec.measurement.tick
                stamp = messages.tick_stamp_ns(k, rate)
                bag.write("measurement", messages.measurement_fields(rec.measurement, stamp), stamp)
                bag.write(
                    "plant_truth",
                    messages.truth_fields(rec.truth, stamp, applied_command_tick=max(-1, k - 1 - delay)),
                    stamp,
                )
                bag.write("estimate", messages.estimate_fields(rec.estimate, stamp), stamp)
                bag.write("command", messages.command_fields(rec.command, stamp), stamp)
                ticks += 1
                if on_record is not None:
                    on_record(rec)
        except DivergenceError as exc:
            diverged = str(exc)
            bag.set_metadata("diverged", {"tick": exc.tick, "reason": exc.reason})
    wall = time.perf_counter() - start
    return RunResult(Path(bag_path), ticks, diverged, wall, ticks / rate)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="simulate", description=__doc__)
    parser.add_argument("bag", type=Path, nargs="?", help="output bag directory (must not exist)")
    add_override_arguments(parser)
    parser.add_argument("--list", action="store_true", help="list every parameter and exit")
    args = parser.parse_args(argv)
    if args.list:
        for pset in scenario_sets(Scenario()).values():
            for spec in pset.specs():
                print(f"{spec.name:22s} {spec.default!s:22s} {spec.allowed():40s} {spec.description}")
        return 0
    if args.bag is None:
        parser.error("the bag directory is required")
    try:
        scenario = scenario_from_flat(overrides_from_args(args))
    except (OverrideError, ParameterError) as exc:
        print(f"simulate: {exc}", file=sys.stderr)
        return 2
    if scenario.loop.duration <= 0.0:
        print("simulate: invalid parameter 'duration' = 0.0: allowed (0, 86400] s offline", file=sys.stderr)
        return 2
    result = simulate_to_bag(scenario, args.bag, label=args.bag.name)
    speed = result.simulated_seconds / result.wall_seconds
    print(
        f"wrote {result.bag_path}: {result.ticks} ticks, {result.simulated_seconds:g} s simulated "
        f"in {result.wall_seconds:.2f} s ({speed:.1f}x real time)"
    )
    if result.diverged:
        print(f"run stopped: {result.diverged}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
