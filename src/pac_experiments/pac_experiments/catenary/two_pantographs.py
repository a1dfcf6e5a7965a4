"""Two pantographs 200 m apart on the FE line (``make two-pantographs``): the trailing one's contact
force against the leading one's and a lone pantograph's at 250-320 km/h, and when the trailing one's
wave reaches the leading one.

Every run: passive benchmark-like 3-mass pantographs (``three_mass_pantograph``) with the EN 50367
target Fm(v) as constant uplift, on the endless window of ``catenary`` laid out for the spacing (the
plant's window, ``fe_plant.window_periods``: 10 spans + ceil(spacing / period) periods), 1 ms steps.
The lone and the two-pantograph runs share that window, so the only difference is the trailing one.

1. Statistics (EN 50318 practice: 20 Hz low-pass, whole spans): both pantographs over the same 8
   spans of line, starting 10 spans after the leading one's start (the trailing wave has reached the
   leading one by then at every speed here); the lone pantograph over the same spans. Start: at
   rest, the heads just touching, the uplift from t = 0 (a static start under both uplifts slackens
   a dropper under the trailing one, which the static solution cannot hold).
2. Wave arrival: from the same start, the leading pantograph's force
   with and without the trailing one; the trailing one's disturbance closes the gap at c - v (c =
   sqrt(T / rho) of the contact wire, 127.7 m/s here): before that the two agree to rounding.

Writes ``reports/catenary/two_pantographs/`` (two_pantographs.md, results.json, results.csv,
sigma.png, arrival.png).
"""

from __future__ import annotations

import argparse
import csv
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from pac_common import jsonio, markdown
from pac_common.contact_statistics import contact_statistics, target_mean_force
from pac_plant.catenary.catenary_file import DEFAULT, load_catenary
from pac_plant.catenary.integrator import ContactSimulation, PassivePantograph
from pac_plant.catenary.line import Line
from pac_plant.catenary.pantographs import three_mass_pantograph
from pac_plant.fe_plant import window_periods

SPEEDS = (250.0, 270.0, 290.0, 300.0, 320.0)
SPACING = 200.0  # m
DT = 1e-3  # s
SETTLE_PERIODS = 10  # periods the leading pantograph runs before the statistics stretch
WINDOW_PERIODS = 8  # periods of the statistics stretch
LOSS_OF_EQUALITY = 1e-3  # N: |F_two - F_lone| above this counts as "different" in the arrival table
OUT = Path("reports/catenary/two_pantographs")


class _Runs:
    """The endless window of ``catenary`` laid out for ``spacing`` and the simulations on it."""

    def __init__(self, catenary: str, spacing: float) -> None:
        self.file = load_catenary(catenary)
        data = self.file.data
        self.spacing = spacing
        periods, start = window_periods(data, spacing)
        self.line = Line(data, self.file.numerics, n_spans=periods * len(data.spans))
        self.period = data.period
        self.x0 = start * data.period

    def simulation(self, speed_kmh: float, two: bool) -> ContactSimulation:
        force = target_mean_force(speed_kmh)
        passive = (PassivePantograph(three_mass_pantograph(), self.spacing, force),) if two else ()
        sim = ContactSimulation(
            self.line,
            three_mass_pantograph(),
            DT,
            speed_kmh / 3.6,
            self.x0,
            endless=True,
            passive=passive,
            window_lag=self.spacing,
        )
        sim.relax_roof_springs(force)  # the uplift is the static force at working height (as FEPlant)
        return sim


def statistics_run(runs: _Runs, speed_kmh: float) -> dict[str, Any]:
    """EN 50318 statistics of the lone pantograph and of both of a pair over the same whole spans."""
    force = target_mean_force(speed_kmh)
    x_from = runs.x0 + SETTLE_PERIODS * runs.period
    x_to = x_from + WINDOW_PERIODS * runs.period
    out: dict[str, Any] = {"speed_kmh": speed_kmh, "uplift_N": force, "spacing_m": runs.spacing}
    out["stretch_m"] = [x_from - runs.x0, x_to - runs.x0]  # along the line, from the leading start
    cpu = 0.0
    for two in (False, True):
        sim = runs.simulation(speed_kmh, two)
        end = x_to + 0.5 * runs.period + (runs.spacing if two else 0.0)  # the last one past x_to
        forces, positions = [], []
        start = time.process_time()
        while sim.position + sim.speed * DT < end:
            sim.step(force)
            forces.append(sim.contact_forces)
            positions.append(sim.contact_positions)
        cpu += time.process_time() - start
        f, x = np.array(forces), np.array(positions)
        names = ("leading", "trailing") if two else ("lone",)
        for k, name in enumerate(names):
            stats = contact_statistics(f[:, k], x[:, k], DT, x_from, x_to)
            out[name] = stats.as_dict()
    out["cpu_s"] = cpu
    return out


def arrival_run(runs: _Runs, speed_kmh: float) -> dict[str, Any]:
    """From rest: the leading pantograph's |F_two - F_lone| against time, and when the trailing
    one's wave can arrive (spacing / (c - v))."""
    c = runs.file.data.contact.wave_speed
    v = speed_kmh / 3.6
    arrival = runs.spacing / (c - v)
    steps = int((arrival + 3.0) / DT)
    force = target_mean_force(speed_kmh)
    lead = {}
    for two in (False, True):
        sim = runs.simulation(speed_kmh, two)
        f = np.empty(steps)
        for k in range(steps):
            sim.step(force)
            f[k] = sim.contact_forces[0]
        lead[two] = f
    t = DT * np.arange(1, steps + 1)
    diff = np.abs(lead[True] - lead[False])
    differs = np.flatnonzero(diff > LOSS_OF_EQUALITY)
    return {
        "speed_kmh": speed_kmh,
        "wave_speed_m_s": c,
        "arrival_s": arrival,
        "max_difference_before_N": float(diff[t < arrival].max()),
        "max_difference_after_N": float(diff[t >= arrival].max()),
        "first_difference_above_1mN_s": float(t[differs[0]]) if len(differs) else None,
        "t": t,
        "difference": diff,
    }


def run(
    catenary: str = DEFAULT, speeds: tuple[float, ...] = SPEEDS, spacing: float = SPACING
) -> dict[str, Any]:
    runs = _Runs(catenary, spacing)
    stats = [statistics_run(runs, v) for v in speeds]
    arrivals = [arrival_run(runs, v) for v in (speeds[0], speeds[-1])]
    return {
        "catenary": runs.file.data.name,
        "spacing_m": spacing,
        "window_spans": runs.line.n_spans,
        "dt_s": DT,
        "pantograph": "3-mass (benchmark-like), passive, uplift = EN 50367 Fm(v)",
        "statistics": stats,
        "arrival": arrivals,
    }


# -- the report ------------------------------------------------------------------------------------------
def _fig_sigma(results: dict[str, Any], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = results["statistics"]
    v = [r["speed_kmh"] for r in rows]
    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    for name, style in (("lone", "k--o"), ("leading", "b-o"), ("trailing", "r-s")):
        ax.plot(v, [r[name]["contact_force_std"] for r in rows], style, label=f"{name} pantograph")
    ax.set_xlabel("speed [km/h]")
    ax.set_ylabel("sigma of the contact force [N]")
    ax.set_title(f"{results['catenary']}: two pantographs {results['spacing_m']:g} m apart")
    ax.grid(True, alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _fig_arrival(arrivals: list[dict[str, Any]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    for a, color in zip(arrivals, ("b", "r"), strict=False):
        ax.semilogy(
            a["t"], np.maximum(a["difference"], 1e-16), color, lw=0.8, label=f"{a['speed_kmh']:g} km/h"
        )
        ax.axvline(a["arrival_s"], color=color, ls="--", lw=1.0)
    ax.set_xlabel("time from start [s]  (dashed: spacing / (c - v))")
    ax.set_ylabel("|F_leading, two - F_lone| [N]")
    ax.set_title("the leading pantograph with and without the trailing one")
    ax.grid(True, alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _f(x: float, digits: int = 1) -> str:
    return f"{x:.{digits}f}"


def write_report(results: dict[str, Any], out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    rows = results["statistics"]
    with open(out / "results.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["speed_kmh", "pantograph", *rows[0]["lone"].keys()])
        for r in rows:
            for name in ("lone", "leading", "trailing"):
                w.writerow([r["speed_kmh"], name, *(f"{v:.6g}" for v in r[name].values())])
    arrivals = [{k: v for k, v in a.items() if k not in ("t", "difference")} for a in results["arrival"]]
    jsonio.write(out / "results.json", {**results, "arrival": arrivals})
    _fig_sigma(results, out / "sigma.png")
    _fig_arrival(results["arrival"], out / "arrival.png")
    stat_rows = []
    for r in rows:
        lone, lead, trail = r["lone"], r["leading"], r["trailing"]
        stat_rows.append(
            [
                f"{r['speed_kmh']:g}",
                _f(r["uplift_N"]),
                _f(lone["contact_force_mean"]),
                _f(lone["contact_force_std"]),
                _f(lead["contact_force_mean"]),
                _f(lead["contact_force_std"]),
                _f(trail["contact_force_mean"]),
                _f(trail["contact_force_std"]),
                _f(trail["contact_force_std"] / lead["contact_force_std"], 2),
                _f(trail["contact_force_min"]),
                _f(trail["contact_loss_percent"], 2),
            ]
        )
    stats_table = markdown.table(
        [
            "v [km/h]",
            "uplift [N]",
            "lone Fm",
            "lone σ",
            "leading Fm",
            "leading σ",
            "trailing Fm",
            "trailing σ",
            "σ trailing / leading",
            "trailing min [N]",
            "trailing loss [%]",
        ],
        stat_rows,
        "r",
    )
    arrival_table = markdown.table(
        [
            "v [km/h]",
            "c - v [m/s]",
            "arrival = 200 m / (c - v) [s]",
            "max |ΔF| before [N]",
            "first |ΔF| > 1 mN [s]",
            "max |ΔF| within 3 s after [N]",
        ],
        [
            [
                f"{a['speed_kmh']:g}",
                _f(a["wave_speed_m_s"] - a["speed_kmh"] / 3.6),
                f"{a['arrival_s']:.3f}",
                f"{a['max_difference_before_N']:.1e}",
                "never"
                if a["first_difference_above_1mN_s"] is None
                else f"{a['first_difference_above_1mN_s']:.3f}",
                _f(a["max_difference_after_N"], 2),
            ]
            for a in arrivals
        ],
        "r",
    )
    stretch = rows[0]["stretch_m"]
    shortfall = [
        100.0 * abs(1.0 - r[name]["contact_force_mean"] / r["uplift_N"])
        for r in rows
        for name in ("lone", "leading", "trailing")
    ]
    below = f"{max(shortfall):.1f} %"
    ratios = [r["trailing"]["contact_force_std"] / r["leading"]["contact_force_std"] for r in rows]
    above = [f"{r['speed_kmh']:g}" for r, q in zip(rows, ratios, strict=True) if q > 1.0]
    under = [f"{r['speed_kmh']:g}" for r, q in zip(rows, ratios, strict=True) if q <= 1.0]
    lead_shift = max(
        abs(r["leading"]["contact_force_std"] / r["lone"]["contact_force_std"] - 1.0) for r in rows
    )
    reading = (
        f"The trailing pantograph's σ is {min(ratios):.2f} to {max(ratios):.2f} times the leading "
        f"one's; larger at {', '.join(above) or 'no speed'} km/h"
        + (f", smaller at {', '.join(under)} km/h" if under else "")
        + f". The leading pantograph's σ is within {100 * lead_shift:.1f} % of the lone one's: the "
        "trailing pantograph changes little ahead of it. Contact loss (a force <= 0 before the "
        "filter) is in the last column."
    )
    text = f"""# Two pantographs {results["spacing_m"]:g} m apart on `{results["catenary"]}`

Generated by `make two-pantographs` (`ros2 run pac_experiments two_pantographs`,
`src/pac_experiments/pac_experiments/catenary/two_pantographs.py`); the numbers are in `results.json` /
`results.csv`. Pantographs: {results["pantograph"]}, both of the pair and the lone one of the
comparison. The endless window is {results["window_spans"]} spans (10 + ceil(200 / 55) = 4 at the
rear for the trailing one), time step {results["dt_s"] * 1e3:g} ms, start at rest with the heads
just touching. Statistics: EN 50318 practice, 20 Hz zero-phase low-pass, over the same 8 whole
spans of line for every pantograph ({stretch[0]:g} to {stretch[1]:g} m after the leading one's start
point, where the trailing one's wave has reached the leading one at every speed here). Fm, σ in N.
The roof springs are at rest in the static state under the uplift (the uplift is the static force
at working height, as the plant sets it): Fm is within {below} of the uplift.

{reading}

## σ of the trailing pantograph against the leading one

{stats_table}

![sigma](sigma.png)

## The leading pantograph equals a lone one until the trailing wave can reach it

From rest, the leading pantograph's force with and without the trailing one. The trailing
pantograph's disturbance runs forward on the contact wire at c = sqrt(T / ρ) =
{results["arrival"][0]["wave_speed_m_s"]:.1f} m/s over ground while the leading one runs away at v:
it closes the 200 m at c - v. Before that time the difference is rounding (the dispersive
beam's faster short waves and the implicit step's exponentially small reach give the 1e-7 N
precursors); after it, it grows to newtons. `tests/test_two_pantographs.py` asserts both sides
(< 1 µN before, > 1 N within 3 s after) at 250 and 320 km/h.

{arrival_table}

![arrival](arrival.png)

## Reading against the published benchmark

The pantograph–catenary interaction benchmark (Bruni, Ambrosio, Carnicero, Cho, Finner, Ikeda,
Kwon, Massat, Stichel, Tur, Zhang, "The results of the pantograph–catenary interaction
benchmark", Vehicle System Dynamics 53(3):412–435, 2015) compares the field's codes on a simple
catenary at 250 and 320 km/h with one and with two pantographs. Neither its input data nor its
result tables could be read here, nor the reference model and result ranges of EN 50318:2018
(one and two pantographs), so this report gives no number of the benchmark and no distance to
it; what is stated in the literature we could read is qualitative: on a simple catenary the
trailing pantograph of a pair rides a wire already set in motion by the leading one, and its
contact force varies more than the leading one's (e.g. Shock and Vibration 2021, article
9922404, an ANCF catenary validated against an inspection vehicle at 378 km/h on the
Chengdu–Chongqing line, whose abstract finds the trailing pantograph not complying with the
assessment standard at 378 km/h). Read the table above with these differences in the data:

- the line is `config/catenaries/benchmark_55m.yaml`, the defaults of a public parameter-entry
  tool that names no source for them (docs/catenary_data.md §2): benchmark-like, not confirmed
  to be the benchmark's catenary; the benchmark's section is finite, ours is an endless
  periodic line (no section ends, no transition spans);
- the pantograph is our reading of the same tool's 3-mass defaults (which spring joins which
  masses is not stated there and its dampings are left at 0; we add a 100 N s/m roof damper:
  docs/catenary.md), the same model for both, pressed by the EN 50367 target
  Fm(v) = 70 + 0.00097 v² N (v in km/h), not by the benchmark's own force (not read here);
- 200 m spacing; no contact-wire irregularity, no wind, 20 Hz filter.

Nothing here was tuned towards any published value.
"""
    (out / "two_pantographs.md").write_text(text)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="two_pantographs",
        description="Two passive pantographs 200 m apart on the FE line at 250-320 km/h: the trailing "
        "one's sigma against the leading one's and a lone one's, and when the trailing wave reaches "
        "the leading one. Writes reports/catenary/two_pantographs/.",
    )
    parser.add_argument("--catenary", default=DEFAULT, help="catenary file or preset (docs/catenary.md)")
    parser.add_argument("--out", type=Path, default=OUT, help="report folder (default: %(default)s)")
    args = parser.parse_args(argv)
    start = time.process_time()
    results = run(args.catenary)
    write_report(results, args.out)
    print(f"two_pantographs: {args.out / 'two_pantographs.md'} ({time.process_time() - start:.1f} s CPU)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
