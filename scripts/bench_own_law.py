#!/usr/bin/env python3
"""How fast a user's law file runs offline: ticks per second at Python speed and compiled.

Usage: scripts/with_env.sh python scripts/bench_own_law.py [--seconds 10] [--repeats 2]

Runs examples/my_law.py as it is (Python speed: the cores stepped tick by tick) and a copy with
``COMPILED = True`` (its functions numba-compiled into the chain and the compiled loop), and pac's
``passive`` and ``pid`` for comparison, each for ``--seconds`` of simulated time on the default
scenario (lumped line) after a short warm-up run (so compiling is not timed; the compile time of
the copy is printed apart). Prints one line per law and repeat (docs/laws.md, "Two speeds").
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from pac_rig.closed_loop import Scenario, build_cores, run_blocks, run_cores
from pac_rig.loop import compile_loop
from pac_rig.simulate import scenario_from_flat

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "my_law.py"


def ticks_per_second(scenario: Scenario) -> tuple[str, float]:
    """(how the loop ran, ticks per wall second) of one run of ``scenario``."""
    cores = build_cores(scenario)
    loop = compile_loop(*cores, scenario.loop.command_delay_ticks)
    start = time.perf_counter()
    if loop is None:
        ticks, how = sum(1 for _ in run_cores(scenario, *cores)), "tick by tick"
    else:
        ticks, how = sum(block.size for block in run_blocks(scenario, cores[0], loop)), "compiled loop"
    return how, ticks / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--seconds", type=float, default=10.0, help="simulated time per run [s]")
    parser.add_argument("--repeats", type=int, default=2, help="timed runs per law")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        compiled = Path(folder) / "my_compiled_law.py"
        compiled.write_text(EXAMPLE.read_text().replace("COMPILED = False", "COMPILED = True"))
        for law in (str(EXAMPLE), str(compiled), "passive", "pid"):
            start = time.perf_counter()
            ticks_per_second(scenario_from_flat({"law": law, "duration": 0.01}))  # compiles or loads
            warm = time.perf_counter() - start
            print(f"{Path(law).name}: warm-up (building, compiling or loading) {warm:.1f} s")
            for _ in range(args.repeats):
                how, rate = ticks_per_second(scenario_from_flat({"law": law, "duration": args.seconds}))
                print(f"{Path(law).name}: {how}, {rate:,.0f} ticks/s")


if __name__ == "__main__":
    main()
