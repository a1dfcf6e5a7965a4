"""``ros2 run pac_experiments fe_experiment``: the control laws on the FE line, judged.

Runs the campaign config/campaigns/fe_laws.yaml (through the compiled batch in this process,
as any campaign whose runs it all takes; resumes like any campaign) into ``--out`` (default
reports/catenary/laws), then writes there from its rows:

- ``laws.md`` / ``goals.json``: sigma (EN 50318: 20 Hz low-pass, whole spans of the window)
  and its change against passive per law and speed, and the goals, each met / not met with
  its numbers;
- ``sigma_vs_speed.png``: sigma and its change against passive per law;
- ``traces.png``: contact force, uplift at the contact point and u over two spans at
  300 km/h, passive against the judged law (two runs repeated tick by tick for their traces).

A row is compared with the passive row of the same speed and pantograph (plant_mass_scale):
a passive run's physics does not depend on sensor noise or command delay (u = F_r).
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from pac_common import jsonio, markdown
from pac_common.contact_statistics import lowpass
from pac_experiments.campaign.results import read_done
from pac_experiments.campaign.run import STATUS_OK
from pac_experiments.campaign.spec import Point, SpecError, expand, load_spec, span_window
from pac_experiments.campaign.spec import same_value as _same

SPEC = Path("config/campaigns/fe_laws.yaml")
OUT = Path("reports/catenary/laws")
JUDGED = "line_adaptive"
SIGMA, MEAN, LOSS = "en50318_contact_force_std", "en50318_contact_force_mean", "en50318_contact_loss_percent"
#: What makes a row not nominal, and the nominal value (the defaults of the rig).
NOMINAL = {"noise_std": [0.0, 0.0], "command_delay_ticks": 1, "plant_mass_scale": 1.0}
#: The robustness cases: name -> the values that differ from nominal.
CASES: dict[str, dict[str, Any]] = {
    "noise 10 µm": {"noise_std": [1e-5, 1e-5]},
    "delay 2 ticks": {"command_delay_ticks": 2},
    "masses x0.8": {"plant_mass_scale": 0.8},
    "masses x1.2": {"plant_mass_scale": 1.2},
    "all, masses x0.8": {"noise_std": [1e-5, 1e-5], "command_delay_ticks": 2, "plant_mass_scale": 0.8},
    "all, masses x1.2": {"noise_std": [1e-5, 1e-5], "command_delay_ticks": 2, "plant_mass_scale": 1.2},
}


def case_of(row: dict[str, Any]) -> str | None:
    """'nominal', a CASES name, or None (a combination the goals do not name)."""
    differs = {k: row.get(k, v) for k, v in NOMINAL.items() if not _same(row.get(k, v), v)}
    if not differs:
        return "nominal"
    for name, values in CASES.items():
        if differs.keys() == values.keys() and all(_same(differs[k], v) for k, v in values.items()):
            return name
    return None


def ok(row: dict[str, Any] | None) -> bool:
    return (
        row is not None and row.get("status") == STATUS_OK and math.isfinite(float(row.get(SIGMA, math.nan)))
    )


def passive_for(rows: list[dict[str, Any]], row: dict[str, Any]) -> dict[str, Any] | None:
    """The passive row of the same speed and pantograph, nominal sensing and delay."""
    for r in rows:
        if (
            r.get("law") == "passive"
            and _same(r["speed_kmh"], row["speed_kmh"])
            and _same(r.get("plant_mass_scale", 1.0), row.get("plant_mass_scale", 1.0))
            and case_of({**r, "plant_mass_scale": 1.0}) == "nominal"
        ):
            return r
    return None


def change_percent(rows: list[dict[str, Any]], row: dict[str, Any]) -> float:
    """sigma change against passive [%] (negative: lower than passive); NaN when either failed."""
    p = passive_for(rows, row)
    if p is None or not (ok(row) and ok(p)):
        return math.nan
    return 100.0 * (float(row[SIGMA]) - float(p[SIGMA])) / float(p[SIGMA])


@dataclass(frozen=True)
class Goal:
    name: str
    met: bool
    numbers: str


def _rows_of(rows: list[dict], law: str, case: str = "nominal", speeds: tuple[float, float] = (0.0, 1e9)):
    out = [r for r in rows if r.get("law") == law and case_of(r) == case]
    return sorted(
        (r for r in out if speeds[0] <= float(r["speed_kmh"]) <= speeds[1]),
        key=lambda r: float(r["speed_kmh"]),
    )


def _changes(rows: list[dict], chosen: list[dict]) -> str:
    return ", ".join(
        f"{float(r['speed_kmh']):g}: {change_percent(rows, r):+.1f} %"
        if ok(r)
        else f"{float(r['speed_kmh']):g}: {r.get('status')}"
        for r in chosen
    )


def goals(rows: list[dict[str, Any]], law: str = JUDGED) -> list[Goal]:
    """The goals for ``law``, each met or not with the numbers it was judged on."""
    out: list[Goal] = []

    def below(chosen: list[dict], percent: float) -> bool:
        return bool(chosen) and all(ok(r) and change_percent(rows, r) <= -percent for r in chosen)

    at300 = _rows_of(rows, law, speeds=(300.0, 300.0))
    out.append(
        Goal("sigma >= 60 % below passive at 300 km/h", below(at300, 60.0), _changes(rows, at300) or "no run")
    )
    band = _rows_of(rows, law, speeds=(250.0, 360.0))
    band_speeds = {float(r["speed_kmh"]) for r in band}
    ends = {250.0, 360.0} <= band_speeds  # both ends of the range must have run
    out.append(
        Goal(
            "sigma >= 50 % below passive at every speed 250-360 km/h",
            ends and below(band, 50.0),
            (_changes(rows, band) or "no run") + ("" if ends else "; 250 and 360 km/h not both run"),
        )
    )
    sweep = _rows_of(rows, law, speeds=(160.0, 400.0))
    speeds = sorted({float(r["speed_kmh"]) for r in sweep})
    # Both ends of the range must have run; the speeds between are those the SPEC chose.
    never_worse = bool(speeds) and speeds[0] <= 160.0 and speeds[-1] >= 400.0 and below(sweep, 0.0)
    worst = max((change_percent(rows, r) for r in sweep if ok(r)), default=math.nan)
    out.append(
        Goal(
            "never worse than passive at any speed 160-400 km/h",
            never_worse,
            f"worst change {worst:+.1f} % at the {len(speeds)} speeds run "
            f"({', '.join(f'{v:g}' for v in speeds)} km/h)"
            + (
                "; failed at " + ", ".join(f"{float(r['speed_kmh']):g}" for r in sweep if not ok(r))
                if any(not ok(r) for r in sweep)
                else ""
            ),
        )
    )
    errors = [
        (
            float(r["speed_kmh"]),
            100.0 * (float(r[MEAN]) - float(r["force_amplitude"])) / float(r["force_amplitude"]),
        )
        for r in sweep
        if ok(r)
    ]
    worst_mean = max((abs(e) for _, e in errors), default=math.nan)
    out.append(
        Goal(
            "mean contact force within 2 % of the target (every speed run)",
            bool(errors) and len(errors) == len(sweep) and worst_mean <= 2.0,
            f"worst |Fm - target| {worst_mean:.2f} % of the target over {len(errors)} speeds",
        )
    )
    lossless = [
        r for r in sweep if (p := passive_for(rows, r)) is not None and ok(p) and float(p[LOSS]) == 0.0
    ]
    lost = [r for r in lossless if not ok(r) or float(r[LOSS]) > 0.0]
    out.append(
        Goal(
            "no contact loss where passive has none",
            bool(lossless) and not lost,
            f"{len(lossless)} speeds where passive keeps contact; "
            + (
                "loss at "
                + ", ".join(f"{float(r['speed_kmh']):g} ({float(r.get(LOSS, math.nan)):.2f} %)" for r in lost)
                if lost
                else "none lost"
            ),
        )
    )
    for name in CASES:
        chosen = _rows_of(rows, law, name)
        out.append(
            Goal(
                f"robust, {name}: >= 30 % below passive, never unstable",
                below(chosen, 30.0),
                _changes(rows, chosen) or "no run",
            )
        )
    return out


def _fmt(v: Any, spec: str = ".4g") -> str:
    if v is None or v == "":
        return "—"
    try:
        f = float(v)
    except (TypeError, ValueError):
        return str(v)
    return format(f, spec) if math.isfinite(f) else "—"


def laws_table(rows: list[dict[str, Any]], laws: list[str]) -> str:
    """One row per nominal run: speed, law, EN 50318 statistics, change vs passive, actuator, F_hat error."""
    header = [
        "v [km/h]",
        "law",
        "target Fm [N]",
        "Fm [N]",
        "σ [N]",
        "σ vs passive",
        "Fm−3σ [N]",
        "max [N]",
        "loss [%]",
        "max |u| [N]",
        "max |du/dt| [kN/s]",
        "max uplift [mm]",
        "F̂ error [% of σ_F]",
        "status",
    ]
    out = []
    nominal = [r for r in rows if case_of(r) == "nominal" and r.get("law") in laws]
    for r in sorted(nominal, key=lambda r: (float(r["speed_kmh"]), laws.index(r["law"]))):
        status = r["status"] if ok(r) else f"{r['status']}: {r.get('reason', '')}"
        change = change_percent(rows, r)
        out.append(
            [
                _fmt(r["speed_kmh"], "g"),
                r["law"],
                _fmt(r.get("force_amplitude"), ".1f"),
                _fmt(r.get(MEAN), ".1f"),
                _fmt(r.get(SIGMA), ".1f"),
                "—" if r["law"] == "passive" else (f"{change:+.1f} %" if math.isfinite(change) else "—"),
                _fmt(r.get("en50318_statistical_min"), ".1f"),
                _fmt(r.get("en50318_contact_force_max"), ".1f"),
                _fmt(r.get(LOSS), ".2f"),
                _fmt(r.get("u_max_abs"), ".0f"),
                _fmt(float(r.get("du_dt_max_abs", math.nan)) / 1e3, ".1f"),
                _fmt(r.get("uplift_max_mm"), ".1f"),
                _fmt(r.get("force_hat_error_percent"), ".0f"),
                status,
            ]
        )
    return markdown.table(header, out, ["r", "l", *["r"] * 11, "l"])


def robustness_table(rows: list[dict[str, Any]], law: str) -> str:
    cases = [r for r in rows if r.get("law") == law and case_of(r) not in (None, "nominal")]
    speeds = sorted({float(r["speed_kmh"]) for r in cases})
    out = []
    for name in ("nominal", *CASES):
        cells = [name]
        for v in speeds:
            r = next((r for r in _rows_of(rows, law, name, (v, v))), None)
            if r is None:
                cells.append("not run")
            elif not ok(r):
                cells.append(str(r["status"]))
            else:
                cells.append(f"{float(r[SIGMA]):.1f}, {change_percent(rows, r):+.1f} %")
        out.append(cells)
    header = ["case", *(f"{v:g} km/h: σ [N], vs passive" for v in speeds)]
    return markdown.table(header, out, ["l", *["r"] * len(speeds)])


def goals_table(found: list[Goal]) -> str:
    return markdown.table(
        ["goal", "met", "numbers"], [[g.name, "**met**" if g.met else "not met", g.numbers] for g in found]
    )


def sigma_figure(rows: list[dict[str, Any]], laws: list[str], path: Path) -> Path:
    fig, (ax_s, ax_c) = plt.subplots(2, 1, figsize=(9, 7.5), sharex=True, constrained_layout=True)
    for i, law in enumerate(laws):
        mine = [r for r in _rows_of(rows, law) if ok(r)]
        if not mine:
            continue
        v = [float(r["speed_kmh"]) for r in mine]
        ax_s.plot(v, [float(r[SIGMA]) for r in mine], "o-", color=f"C{i}", label=law, ms=4)
        if law != "passive":
            ax_c.plot(v, [change_percent(rows, r) for r in mine], "o-", color=f"C{i}", label=law, ms=4)
    for level, text in ((-60.0, "goal at 300 km/h"), (-50.0, "goal 250-360 km/h"), (0.0, "passive")):
        ax_c.axhline(level, color="0.4", ls="--", lw=0.8)
        ax_c.text(ax_c.get_xlim()[0], level, f" {text}", va="bottom", fontsize=7, color="0.3")
    ax_s.set_yscale("log")
    ax_s.set_ylabel(r"$\sigma$ (EN 50318, 20 Hz) [N]")
    ax_s.set_title("FE line, paper's pantograph, fixed datum: contact-force standard deviation")
    ax_s.legend(fontsize=8)
    ax_c.set_ylabel(r"$\sigma$ change vs passive [%]")
    ax_c.set_xlabel("speed [km/h]")
    ax_c.legend(fontsize=8)
    for ax in (ax_s, ax_c):
        ax.grid(alpha=0.3)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def traces(point: Point) -> dict[str, np.ndarray]:
    """Contact force, uplift and u of one point's run, tick by tick (stops early at a divergence)."""
    from pac_rig.closed_loop import DivergenceError, run

    cols: dict[str, list[float]] = {k: [] for k in ("t", "F", "uplift", "u")}
    try:
        for rec in run(point.built()):
            cols["t"].append(rec.truth.time)
            cols["F"].append(rec.truth.contact_force)
            cols["uplift"].append(rec.truth.contact_uplift)
            cols["u"].append(rec.command.u)
    except DivergenceError:
        pass
    return {k: np.array(v) for k, v in cols.items()}


def traces_figure(
    spec_points: list[Point], law: str, speed: float, path: Path, run_traces: Callable = traces
) -> Path | None:
    """Force (20 Hz), uplift and u over the last two spans of the window, passive vs ``law``."""
    chosen = {
        p.values.get("law"): p
        for p in spec_points
        if p.values.get("law") in ("passive", law)
        and _same(p.values.get("speed_kmh"), speed)
        and case_of(p.values) == "nominal"
    }
    if set(chosen) != {"passive", law}:
        return None
    from pac_rig.simulate import scenario_from_flat

    t_end = chosen["passive"].window[1]
    span_time = span_window(scenario_from_flat(chosen["passive"].values), (0.0, 1.0))[1]
    fig, axes = plt.subplots(3, 1, figsize=(11, 8), sharex=True, constrained_layout=True)
    for name, color in (("passive", "C0"), (law, "C3")):
        tr = run_traces(chosen[name])
        if tr["t"].size < 100:
            continue
        w = (tr["t"] >= t_end - 2 * span_time) & (tr["t"] <= t_end)
        x = tr["t"][w] / span_time
        axes[0].plot(x, lowpass(tr["F"], 1e-3)[w], color, lw=1.0, label=name)
        axes[1].plot(x, 1e3 * tr["uplift"][w], color, lw=1.0, label=name)
        axes[2].plot(x, tr["u"][w], color, lw=1.0, label=name)
    for ax, label in zip(
        axes,
        ("contact force, 20 Hz low-pass [N]", "wire uplift at the contact [mm]", "actuator force u [N]"),
        strict=True,
    ):
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
        ax.legend(loc="upper right", fontsize=8)
    axes[-1].set_xlabel("position [spans from the start support]")
    axes[0].set_title(f"FE line, {speed:g} km/h: passive vs {law}, last two spans of the window")
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def write(
    spec_path: Path, out: Path, law: str = JUDGED, figures: bool = True, traces_runs: bool = True
) -> str:
    """laws.md, goals.json and the figures in ``out`` from the campaign's rows there."""
    spec = load_spec(spec_path)
    points = expand(spec)
    done = read_done(out)
    rows = [done[p.key] for p in points if p.key in done]
    laws = list(dict.fromkeys(r["law"] for r in rows))
    found = goals(rows, law)
    if figures:
        sigma_figure(rows, laws, out / "sigma_vs_speed.png")
        if traces_runs:
            traces_figure(points, law, 300.0, out / "traces.png")
    a, b = spec.window_spans or (math.nan, math.nan)
    text = "\n".join(
        [
            "# The control laws on the FE line",
            "",
            "Generated by `make fe-experiment` (src/pac_experiments/pac_experiments/catenary/experiment.py) "
            f"from the campaign `{spec_path}` (rows: results.csv, report.md here); method: docs/catenary.md.",
            "",
            f"FE line (10-span moving window, endless), the paper's 2-DOF pantograph, z1, z2 from the fixed "
            f"datum, F_r = the EN 50367 target Fm(v); statistics over spans {a:g} to {b:g} of the run "
            f"({b - a:g} whole spans after a run-in of {a:g}), EN 50318: contact force low-passed at 20 Hz "
            "(zero-phase), loss on the unfiltered force. σ change against the passive run of the same speed "
            "and pantograph. F̂ error: RMS(F̂ − F) / σ_F over the window (unfiltered), F̂ = the observer's "
            "`contact_force_hat`.",
            "",
            f"## Goals for `{law}`",
            "",
            goals_table(found),
            "",
            "## Every law, nominal conditions",
            "",
            laws_table(rows, laws),
            "",
            f"## Robustness of `{law}` (σ and its change against passive with the same pantograph)",
            "",
            robustness_table(rows, law),
            "",
            "![sigma vs speed](sigma_vs_speed.png)",
            "",
            "![traces](traces.png)" if (out / "traces.png").exists() else "(traces.png: not drawn this time)",
            "",
        ]
    )
    (out / "laws.md").write_text(text)
    jsonio.write(
        out / "goals.json",
        {
            "law": law,
            "goals": [{"goal": g.name, "met": g.met, "numbers": g.numbers} for g in found],
            "change_vs_passive_percent": {
                f"{r['law']} {float(r['speed_kmh']):g} {case_of(r)}": change_percent(rows, r)
                for r in rows
                if r["law"] != "passive"
            },
        },
    )
    return text


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="fe_experiment", description=__doc__)
    parser.add_argument("--spec", type=Path, default=SPEC)
    parser.add_argument("--out", type=Path, default=OUT)
    parser.add_argument("--law", default=JUDGED, help="the law the goals judge")
    parser.add_argument("--workers", type=int, help="threads (or Dask workers) (default: cores)")
    parser.add_argument("--chunk-size", type=int, help="runs per Dask task (default: the campaign's)")
    parser.add_argument("--report-only", action="store_true", help="no runs: write up the rows in --out")
    parser.add_argument(
        "--no-traces", action="store_true", help="skip traces.png (it repeats two runs tick by tick)"
    )
    args = parser.parse_args(argv)
    if not args.report_only:
        from pac_experiments.campaign.cli import main as campaign_main

        extra = ["--workers", str(args.workers)] if args.workers else []
        extra += ["--chunk-size", str(args.chunk_size)] if args.chunk_size else []
        code = campaign_main([str(args.spec), "--out", str(args.out), *extra])
        if code not in (0, 1):  # 1: some tasks lost; the rows there are still worth writing up
            return code
    try:
        print(write(args.spec, args.out, args.law, traces_runs=not args.no_traces))
    except SpecError as exc:
        for line in exc.errors:
            print(f"fe_experiment: {line}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
