"""``ros2 run pac_analysis re_estimate <bag> [-p name:=value ...]``: the observer core over a bag, offline.

Feeds the bag's ``measurement`` messages (z1, z2 and the applied force) to the
observer core and compares its estimates with the recorded ``estimate`` messages.
It feeds exactly the ticks the live observer processed (those with a recorded
estimate; a gap is bridged the same way the node bridged it), so a lock-step or
offline bag is reproduced to the last bit, and so is a real-time bag whose
estimates were all recorded.  Observer parameters: the bag's own (offline bags
record them), else the shipped defaults, overridden by ``-p``/``--params-file``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import numpy as np

from pac_bag.reader import BagError, read_bag
from pac_common.parameters import ParameterError, RateParameters
from pac_model.parameters import PantographParameters, TrackParameters
from pac_observer.observer import AdaptiveObserver, ObserverDivergedError
from pac_observer.parameters import ObserverParameters
from pac_rig.cli import OverrideError, add_override_arguments, overrides_from_args

FIELDS = ("z_hat", "theta_hat", "stiffness_hat", "contact_force_hat", "innovation")


def re_estimate(bag_path: Path, overrides: dict) -> dict:
    bag = read_bag(bag_path, topics=["measurement", "estimate"])
    meas = bag.topics.get("measurement")
    if meas is None or not len(meas):
        raise BagError(f"{bag_path}: no 'measurement' messages to re-estimate from")
    values = {**bag.metadata.get("parameters", {}), **overrides}
    panto = PantographParameters.from_mapping(values)
    track = TrackParameters.from_mapping(values)
    params = ObserverParameters.from_mapping(values)
    rate = RateParameters.from_mapping(values)
    ticks, first = np.unique(meas["tick"], return_index=True)
    recorded = bag.topics.get("estimate")
    if recorded is not None and len(recorded):
        rec_ticks, rec_idx = np.unique(recorded["tick"], return_index=True)
        feed = np.isin(ticks, rec_ticks)
    else:
        rec_ticks, rec_idx, feed = np.array([], dtype=int), np.array([], dtype=int), np.ones(ticks.size, bool)
    core = AdaptiveObserver(panto, track, params, rate.sample_period)
    out: dict[str, list] = {f: [] for f in FIELDS}
    done = []
    for tick, i in zip(ticks[feed], first[feed], strict=True):
        try:
            est = core.update(
                int(tick), (float(meas["z1"][i]), float(meas["z2"][i])), float(meas["actuator_force"][i])
            )
        except ObserverDivergedError as exc:
            raise BagError(f"{bag_path}: the observer diverged at tick {exc.tick}: {exc.reason}") from None
        done.append(int(tick))
        for f in FIELDS:
            out[f].append(np.asarray(getattr(est, f), dtype=float))
    fields: dict[str, dict[str, Any]] = {}
    result: dict[str, Any] = {"ticks": len(done), "compared": 0, "fields": fields}
    if recorded is not None and rec_ticks.size:
        common, ia, ib = np.intersect1d(np.array(done), rec_ticks, return_indices=True)
        result["compared"] = int(common.size)
        for f in FIELDS:
            mine = np.array(out[f])[ia]
            theirs = np.asarray(recorded[f][rec_idx][ib], dtype=float)
            diff = np.abs(mine - theirs)
            scale = np.maximum(np.abs(theirs), 1e-300)
            fields[f] = {
                "max_abs_diff": float(diff.max()) if diff.size else 0.0,
                "max_rel_diff": float((diff / scale).max()) if diff.size else 0.0,
                "identical": bool(np.array_equal(mine, theirs)),
            }
    return result


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="re_estimate", description=__doc__)
    parser.add_argument("bag", type=Path)
    add_override_arguments(parser)
    args = parser.parse_args(argv)
    try:
        overrides = overrides_from_args(args)
    except OverrideError as exc:
        print(f"re_estimate: {exc}", file=sys.stderr)
        return 2
    try:
        result = re_estimate(args.bag, overrides)
    except ParameterError as exc:
        print(f"re_estimate: {exc}", file=sys.stderr)
        return 2
    except BagError as exc:
        print(f"re_estimate: {exc}", file=sys.stderr)
        return 1
    print(f"re-estimated {result['ticks']} ticks, compared {result['compared']} with the recorded estimates")
    for f, r in result["fields"].items():
        verdict = (
            "identical"
            if r["identical"]
            else f"max |diff| {r['max_abs_diff']:.3g} (rel {r['max_rel_diff']:.3g})"
        )
        print(f"  {f:18s} {verdict}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
