#!/usr/bin/env python3
"""What the moving window changes: each run with ``fe_window_spans`` against the same run on the
whole line (docs/catenary.md, "A moving window on a whole line").

Usage: scripts/with_env.sh python scripts/window_fidelity.py [--catenary realistic_3km]
       [--speeds 250 300 350] [--seeds 2 3 4] [--windows 10 16] [--laws passive line_adaptive]

Runs the points of config/campaigns/realistic_laws.yaml (its statistics window and force target)
on ``realistic_electromechanical`` with the head-balance estimate, in process, and prints one line
per run: EN 50318 sigma and contact loss, then for a windowed run its sigma change and the rms
and largest difference of the raw contact force from the whole line's run, tick by tick.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from pac_experiments.campaign.run import en50318_measures
from pac_experiments.campaign.spec import load_spec, resolve
from pac_rig.closed_loop import build_cores, run_blocks
from pac_rig.loop import compile_loop

SPEC = Path(__file__).resolve().parents[1] / "config" / "campaigns" / "realistic_laws.yaml"


def run(values: dict) -> tuple[np.ndarray, float, float]:
    """(raw contact force per tick, EN 50318 sigma [N], contact loss [%]) of one point."""
    scenario, _, window = resolve(load_spec(SPEC), values)
    plant, observer, controller = build_cores(scenario)
    loop = compile_loop(plant, observer, controller, scenario.loop.command_delay_ticks)
    if loop is None:
        raise SystemExit(f"window_fidelity: law {values['law']} has no compiled loop")
    ticks = np.concatenate(list(run_blocks(scenario, plant, loop)))
    dt = scenario.loop.sample_period
    m = en50318_measures(
        np.arange(ticks.size) * dt,
        ticks["contact_force"],
        ticks["u"],
        ticks["contact_force_hat"],
        ticks["contact_uplift"],
        window,
        dt,
    )
    return ticks["contact_force"], m["en50318_contact_force_std"], m["en50318_contact_loss_percent"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--catenary", default="realistic_3km")
    parser.add_argument("--speeds", type=float, nargs="+", default=[250.0, 300.0, 350.0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[2, 3, 4])
    parser.add_argument("--windows", type=float, nargs="+", default=[10.0, 16.0])
    parser.add_argument("--laws", nargs="+", default=["passive", "line_adaptive"])
    args = parser.parse_args()
    for speed in args.speeds:
        for seed in args.seeds:
            for law in args.laws:
                point = {
                    "scenario": "realistic_electromechanical",
                    "catenary": args.catenary,
                    "observer": "head_balance",
                    "law": law,
                    "line_seed": seed,
                    "speed_kmh": speed,
                }
                whole, sigma_whole, loss_whole = run({**point, "fe_window_spans": 0.0})
                label = f"{speed:.0f} km/h line {seed} {law:13s}"
                print(f"{label} whole line  sigma {sigma_whole:7.3f} N  loss {loss_whole:.4f} %")
                for spans in args.windows:
                    force, sigma, loss = run({**point, "fe_window_spans": spans})
                    gap = np.abs(force - whole)
                    print(
                        f"{label} {spans:4g} spans  sigma {sigma:7.3f} N  "
                        f"loss {loss:.4f} %  sigma {100 * (sigma / sigma_whole - 1):+.2f} %  "
                        f"F - F_whole rms {np.sqrt(np.mean(gap**2)):.3f} N, largest {gap.max():.2f} N",
                        flush=True,
                    )


if __name__ == "__main__":
    main()
