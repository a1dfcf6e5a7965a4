"""``ros2 run pac_experiments fe_live``: the four-process rig in real time on the FE line, judged
against the offline campaign.

Takes one point of the FE campaign (default: ``law=line_adaptive`` at 300 km/h, nominal,
from config/campaigns/fe_laws.yaml), runs it live (plant, observer, controller, recorder as
``ros2 run`` processes, real time at 1 kHz, a free ROS domain, loopback discovery), reads the
bag back and writes ``reports/catenary/live/`` (live.md, live.json, live.png): the EN 50318
statistics over the same whole-span window as offline, beside the campaign's row for the
same point (sigma within 10 % is the goal), the ticks in the bag per topic, and the loop
timing. The bag stays in bags/ (not committed).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from datetime import datetime
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from pac_common import jsonio, markdown
from pac_common.contact_statistics import lowpass
from pac_experiments.campaign.results import read_done
from pac_experiments.campaign.run import en50318_measures
from pac_experiments.campaign.spec import Point, expand, load_spec
from pac_experiments.catenary.experiment import OUT, SIGMA, SPEC, case_of, passive_for

LIVE_OUT = Path("reports/catenary/live")
#: The goal: live sigma within this fraction of the offline sigma.
SIGMA_TOLERANCE = 0.10


def choose(points: list[Point], law: str, speed: float, seed: int | None = None) -> Point:
    """The campaign's nominal point of ``law`` at ``speed``; with ``seed``, its point on that line
    seed (a campaign over drawn lines, e.g. config/campaigns/realistic_laws.yaml)."""
    for p in points:
        if seed is not None:
            if p.values.get("law") == law and float(p.values.get("speed_kmh", math.nan)) == speed:
                if int(p.values.get("line_seed", -1)) == seed:
                    return p
            continue
        if p.values.get("law") == law and float(p.values.get("speed_kmh", math.nan)) == speed:
            if case_of(p.values) == "nominal":
                return p
    on = f" on line seed {seed}" if seed is not None else ""
    raise ValueError(f"no nominal point with law {law} at {speed:g} km/h{on} in the campaign")


def loop_parameters(point: Point) -> dict[str, Any]:
    """The point's values the loop nodes take (``duration`` goes to the rig itself; a ``scenario``
    the rig expands into the nodes' values)."""
    from pac_rig.configs import parameter_sets
    from pac_rig.nodes import LOOP_NODES

    names = {s.name for n in LOOP_NODES for c in parameter_sets(n) for s in c.specs()} | {"scenario"}
    return {k: v for k, v in point.values.items() if k in names and k != "duration"}


def bag_series(bag: Any, rate_hz: float) -> dict[str, np.ndarray]:
    """Per plant tick: time, F, uplift (plant_truth), u (command) and F_hat (estimate), NaN where a
    topic has no message for the tick."""
    truth = bag.topics["plant_truth"]
    ticks, first = np.unique(truth["tick"], return_index=True)
    out = {
        "tick": ticks,
        "t": ticks / rate_hz,
        "F": truth["contact_force"][first],
        "uplift": truth["contact_uplift"][first],
    }
    for topic, field, name in (("command", "u", "u"), ("estimate", "contact_force_hat", "F_hat")):
        data = bag.topics.get(topic)
        values = np.full(ticks.size, np.nan)
        if data is not None and len(data):
            t, i = np.unique(data["tick"], return_index=True)
            idx = np.searchsorted(ticks, t)
            keep = (idx < ticks.size) & (ticks[np.minimum(idx, ticks.size - 1)] == t)
            values[idx[keep]] = data[field][i][keep]
        # A tick the topic skipped (real time keeps only the newest sample) holds the previous value.
        for k in range(1, values.size):
            if not math.isfinite(values[k]):
                values[k] = values[k - 1]
        out[name] = values
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="fe_live", description=__doc__)
    parser.add_argument("--spec", type=Path, default=SPEC)
    parser.add_argument("--campaign", type=Path, default=OUT, help="the campaign's output (its offline row)")
    parser.add_argument("--law", default="line_adaptive")
    parser.add_argument("--speed", type=float, default=300.0)
    parser.add_argument("--seed", type=int, default=None, help="the campaign's point on this line seed")
    parser.add_argument("--out", type=Path, default=LIVE_OUT)
    parser.add_argument("--bag", type=Path, default=None, help="default bags/fe_live_<time>")
    parser.add_argument(
        "--analyse-only",
        action="store_true",
        help="no run: write up the existing --bag (e.g. once the offline row exists)",
    )
    args = parser.parse_args(argv)
    from pac_rig.simulate import scenario_from_flat

    point = choose(expand(load_spec(args.spec)), args.law, args.speed, args.seed)
    scenario = scenario_from_flat(point.values)
    duration = scenario.loop.duration
    bag_path = args.bag or Path("bags") / f"fe_live_{datetime.now():%Y%m%d_%H%M%S}"
    codes: dict[str, int | None] = {}
    if args.analyse_only:
        if args.bag is None:
            print("fe_live: --analyse-only needs --bag", file=sys.stderr)
            return 2
        logs = bag_path.parent / f"{bag_path.name}_logs" / "exit_codes.json"
        codes = json.loads(logs.read_text()) if logs.exists() else {}
    else:
        codes = run_live(bag_path, duration, point, args)
    return write_up(bag_path, codes, point, scenario, duration, args)


def run_live(
    bag_path: Path, duration: float, point: Point, args: argparse.Namespace
) -> dict[str, int | None]:
    """The rig in real time for ``duration`` (s), recording to ``bag_path``; the processes' exit codes."""
    from pac_experiments.demo import free_domain
    from pac_rig.launcher import Rig

    with free_domain() as domain_id:
        print(
            f"fe_live: {args.law} at {args.speed:g} km/h on the FE line, {duration:g} s, domain {domain_id}"
        )
        # The FE plant's start (assembly, compiled step) can take tens of seconds on a loaded
        # machine, silent on the topics: the recorder must not take that for the end.
        params = {"all": loop_parameters(point), "recorder": {"idle_timeout": 120.0}}
        rig = Rig(bag_path, duration=duration, domain_id=domain_id, params=params)
        try:
            rig.start()
            rig.wait_finished(timeout=180.0 + 20.0 * duration)
        finally:
            codes = rig.stop()
    jsonio.write(rig.log_dir / "exit_codes.json", codes)
    return codes


def write_up(
    bag_path: Path,
    codes: dict[str, int | None],
    point: Point,
    scenario: Any,
    duration: float,
    args: argparse.Namespace,
) -> int:
    """live.md, live.json, live.png from the bag, beside the campaign's offline row."""
    from pac_analysis.metrics import compute_metrics, loop_timing, timing_table
    from pac_bag.reader import read_bag

    bag = read_bag(bag_path)
    s = bag_series(bag, scenario.loop.rate_hz)
    live = en50318_measures(
        s["t"], s["F"], s["u"], s["F_hat"], s["uplift"], point.window, scenario.loop.sample_period
    )
    done = read_done(args.campaign)
    offline = done.get(point.key)
    if args.seed is None:
        passive = passive_for(list(done.values()), {**point.values, "plant_mass_scale": 1.0})
    else:  # the passive run on the same line and train as the offline row (a row holds no scenario)
        same = ("catenary", "actuator", "sensors", "speed_kmh", "line_seed")
        ref = offline or {}
        passive = next(
            (
                r
                for r in done.values()
                if r.get("law") == "passive" and all(r.get(k) == ref.get(k) for k in same)
            ),
            None,
        )
    sigma_passive = float(passive[SIGMA]) if passive and passive.get("status") == "ok" else math.nan
    raw = compute_metrics(bag, *point.window)
    timing = loop_timing(bag)
    expected = int(round(duration * scenario.loop.rate_hz))
    sigma_live = live["en50318_contact_force_std"]
    sigma_off = float(offline[SIGMA]) if offline and offline.get("status") == "ok" else math.nan
    deviation = (sigma_live - sigma_off) / sigma_off if math.isfinite(sigma_off) else math.nan
    every_tick = raw.ticks_missing == 0 and raw.ticks_recorded == expected
    args.out.mkdir(parents=True, exist_ok=True)
    fig, axes = plt.subplots(3, 1, figsize=(11, 8), sharex=True, constrained_layout=True)
    span_time = point.window[1] - point.window[0]
    for ax, key, label in (
        (axes[0], "F", "contact force, 20 Hz low-pass [N]"),
        (axes[1], "uplift", "wire uplift at the contact [mm]"),
        (axes[2], "u", "actuator force u [N]"),
    ):
        y = (
            lowpass(s["F"], scenario.loop.sample_period)
            if key == "F"
            else s[key] * (1e3 if key == "uplift" else 1.0)
        )
        ax.plot(s["t"], y, "C3", lw=0.7)
        ax.axvspan(*point.window, color="0.9", zorder=0)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel("time [s] (shaded: the statistics' whole-span window)")
    axes[0].set_title(f"live rig, FE line, {args.law} at {args.speed:g} km/h ({span_time:.2f} s window)")
    fig.savefig(args.out / "live.png", dpi=100)
    plt.close(fig)
    result = {
        "law": args.law,
        "speed_kmh": args.speed,
        "bag": str(bag_path),
        "recorded": datetime.fromtimestamp((bag_path / "metadata.yaml").stat().st_mtime).isoformat(
            timespec="seconds"
        ),
        "exit_codes": codes,
        "window_s": list(point.window),
        "live": live,
        "offline": {k: offline.get(k) for k in (SIGMA, "en50318_contact_force_mean", "status")}
        if offline
        else None,
        "sigma_deviation_percent": 100.0 * deviation,
        "offline_passive_sigma": sigma_passive,
        "sigma_within_10_percent": bool(abs(deviation) <= SIGMA_TOLERANCE)
        if math.isfinite(deviation)
        else False,
        "ticks_expected": expected,
        "plant_ticks_recorded": raw.ticks_recorded,
        "every_plant_tick_in_bag": every_tick,
        "timing": timing.as_dict(),
    }
    jsonio.write(args.out / "live.json", result)
    offline_mean = float(offline["en50318_contact_force_mean"]) if offline else math.nan
    met = "met" if result["sigma_within_10_percent"] else "not met"
    rows = [
        ["Fm [N]", f"{live['en50318_contact_force_mean']:.2f}", f"{offline_mean:.2f}"],
        ["σ [N] (20 Hz)", f"{sigma_live:.2f}", f"{sigma_off:.2f}"],
        ["σ live vs offline", f"{100 * deviation:+.1f} % (goal: within ±10 %: {met})", ""],
        [
            f"σ vs the offline passive run ({sigma_passive:.2f} N)",
            f"{100 * (sigma_live - sigma_passive) / sigma_passive:+.1f} %",
            f"{100 * (sigma_off - sigma_passive) / sigma_passive:+.1f} %",
        ],
        ["contact loss [%]", f"{live['en50318_contact_loss_percent']:.2f}", ""],
        ["max |u| [N]", f"{np.nanmax(np.abs(s['u'])):.0f}", ""],
        [
            "plant ticks in the bag",
            f"{raw.ticks_recorded} of {expected} ({'every tick' if every_tick else 'NOT every tick'})",
            "",
        ],
    ]
    text = "\n".join(
        [
            f"# Live: the four-process rig in real time on the FE line, `{args.law}` at {args.speed:g} km/h",
            "",
            "Generated by `make fe-live` (src/pac_experiments/pac_experiments/catenary/live.py), recorded "
            f"{result['recorded']}; parameters: the campaign point (fe_datum fixed, EN 50367 target), "
            f"{duration:g} s, statistics over the same whole spans as offline, t in "
            f"[{point.window[0]:.3f}, {point.window[1]:.3f}] s.",
            "",
            markdown.table(["", "live", "offline (campaign)"], rows, ["l", "r", "r"]),
            "",
            "## Loop timing (from the bag)",
            "",
            timing_table({"live": timing}),
            f"Exit codes: {codes}.",
            "",
            "![live](live.png)",
            "",
        ]
    )
    text = _nan_text(text)
    (args.out / "live.md").write_text(text)
    print(text)
    return 0 if all(c == 0 for c in codes.values()) else 1


def _nan_text(text: str) -> str:
    """A number that does not exist (the offline row not run yet) reads as such."""
    return text.replace("+nan %", "not run").replace("| nan |", "| not run |")


if __name__ == "__main__":
    sys.exit(main())
