"""What a leading pantograph gains when its learned feedforward is reshaped, knowing both
pantographs' responses, to spare its passive follower's sigma (``make realistic-pair-bound``).

An active leading pantograph makes its passive follower worse (``realistic_pair``), and
line_adaptive's effort weight trades the leader's gain for the follower's along one curve. Is that
the law or the line? This experiment measures, per line, the best reshaping of the pattern the
leader learned (each band about a learned harmonic, each stretch of the run, each phase), chosen
with what no law knows: both pantographs' measured responses on that line. It estimates what a law
that learned the pair's responses could reach; it is not a law, and not a proof of a limit (a
richer family of patterns could do more).

Per line, at the speed (the pair's runs, ``pair.simulate``):

1. the passive pair (P) and line_adaptive leading (A, the pair's ``active leading``);
2. the pattern p(t) = u(t) - F_r the leader applied in A, split into bands about the span
   harmonics the law learns (f1 = v / the layout's mean span, harmonics h f1 up to the run's
   line_max_frequency; band edges 0.4 f1, (h + 0.5) f1, last (H + 0.6) f1), each band into
   ``segments`` stretches of the run (hat weights that sum to one), each with its twin a quarter
   period behind (the Hilbert transform): the basis b_j(t);
3. one run per b_j, the leader pressing F_r + b_j(t) open loop (feedforward_law.py): each
   pantograph's low-passed force (EN 50318, 20 Hz) over the stretch judged, minus P's: g_j;
4. where contact holds the forces are linear in the feedforward, so each pantograph's sigma^2 is a
   quadratic in the weights x of F_r + sum x_j b_j (:func:`sigma_quadratics`). The weights that
   minimise sigma_L^2 + lambda sigma_T^2 for the smallest lambda of ``LAMBDAS`` whose predicted
   follower sigma is at most ``FOLLOWER_MARGIN`` of passive's (:func:`best_weights`);
5. one run with those weights (V): both pantographs' sigma and contact loss as measured.

Writes ``reports/realistic/pair_bound/`` (bound.md, results.csv).
"""

from __future__ import annotations

import argparse
import os
import statistics as stats_lib
import sys
import tempfile
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from pac_common import markdown
from pac_common.contact_statistics import lowpass, position_window
from pac_experiments.campaign.summary import Interval, percent_change
from pac_experiments.realistic import REPORT_LINES, feedforward_law, write_results
from pac_experiments.realistic.pair import PANTOGRAPHS, SPEED, Config, pantograph_statistics, simulate

SEEDS = REPORT_LINES
#: lambda, the follower's weight against the leader's, tried in this order (the smallest that keeps
#: the follower's predicted sigma within the margin wins).
LAMBDAS = (0.0, 0.1, 0.3, 0.5, 1.0, 1.5, 2.0, 3.0, 5.0, 10.0, 30.0, 100.0)
#: The follower's predicted sigma must be at most this share of passive's: 1 % below, since the
#: linear prediction does not see the contact the follower loses. Set before any run; on design
#: lines 0-9 the runs came out 0.2-2.0 points above the prediction, so it does not cover it all.
FOLLOWER_MARGIN = 0.99
#: Stretches of the run per band (hat weights): on design lines 0-9 at 300 km/h 3 gave the leader
#: -9.8 % against -7.3 % with 1, its follower -0.4 % against -0.8 % (docs/realistic_scenario.md).
SEGMENTS = 3
LAW_FILE = Path(feedforward_law.__file__)
OUT = Path("reports/realistic/pair_bound")


@dataclass(frozen=True)
class Quadratic:
    """sigma^2(x) = x' a x + 2 b' x + c of one pantograph's force over the stretch judged."""

    a: np.ndarray
    b: np.ndarray
    c: float

    def sigma(self, x: np.ndarray) -> float:
        return float(np.sqrt(max(float(x @ self.a @ x + 2.0 * self.b @ x + self.c), 0.0)))


def sigma_quadratics(passive: np.ndarray, responses: np.ndarray) -> Quadratic:
    """The quadratic of sigma^2 of ``passive + responses @ x`` (passive: m samples; responses: m x n,
    one column per basis run): exact where the force is linear in the feedforward."""
    f0 = passive - passive.mean()
    g = responses - responses.mean(axis=0)
    m = len(f0)
    return Quadratic(g.T @ g / m, g.T @ f0 / m, float(f0 @ f0 / m))


def best_weights(
    leading: Quadratic,
    trailing: Quadratic,
    margin: float = FOLLOWER_MARGIN,
    lambdas: tuple[float, ...] = LAMBDAS,
) -> tuple[float, np.ndarray] | None:
    """(lambda, x): the weights minimising sigma_L^2 + lambda sigma_T^2 for the first lambda whose
    predicted follower sigma is at most ``margin`` of passive's; None if none is."""
    n = len(leading.b)
    bound = margin * np.sqrt(trailing.c)
    for lam in lambdas:
        # a tiny ridge: two basis runs can move the forces almost alike (the normal equations'
        # matrix is then near singular, and its null direction changes no sigma)
        m = leading.a + lam * trailing.a + 1e-9 * np.trace(leading.a + trailing.a) * np.eye(n)
        x = np.linalg.solve(m, -(leading.b + lam * trailing.b))
        if trailing.sigma(x) <= bound:
            return lam, x
    return None


def band_edges(f1: float, max_frequency: float) -> list[float]:
    """The bands' edges [Hz] about the harmonics h f1 <= max_frequency (at least the first)."""
    harmonics = max(1, int(max_frequency / f1 + 1e-9))
    return [0.4 * f1] + [(h + 0.5) * f1 for h in range(1, harmonics)] + [(harmonics + 0.6) * f1]


def basis(pattern: np.ndarray, dt: float, edges: list[float], segments: int) -> list[np.ndarray]:
    """The pattern's band parts, each on ``segments`` hat-weighted stretches, each with its twin a
    quarter period behind (the Hilbert transform's imaginary part)."""
    from scipy.signal import butter, hilbert, sosfiltfilt

    n = len(pattern)
    if segments == 1:
        weights = [np.ones(n)]
    else:
        ticks = np.arange(n)
        nodes = np.linspace(0, n - 1, segments)
        weights = [np.interp(ticks, nodes, np.eye(segments)[j]) for j in range(segments)]
    out = []
    for low, high in zip(edges[:-1], edges[1:], strict=True):
        band = sosfiltfilt(butter(4, [low, high], btype="band", fs=1.0 / dt, output="sos"), pattern)
        twin = np.imag(hilbert(band))
        for w in weights:
            out += [band * w, twin * w]
    return out


def _feedforward(
    seed: int, speed: float, pattern: np.ndarray, folder: str
) -> tuple[np.ndarray, float, float, float]:
    """A pair run with the leader pressing F_r + pattern open loop."""
    path = os.path.join(folder, "pattern.npy")
    np.save(path, pattern)
    os.environ[feedforward_law.TABLE_VARIABLE] = path
    return simulate(seed, (str(LAW_FILE), 0, {}), speed)


def _measured(out: np.ndarray, first: float, last: float, dt: float) -> list[tuple[float, float]]:
    """Each pantograph's (sigma, contact loss %) over the stretch."""
    return [
        (st.contact_force_std, st.contact_loss_percent) for st in pantograph_statistics(out, first, last, dt)
    ]


def run_line(seed: int, speed: float = SPEED, segments: int = SEGMENTS) -> dict[str, Any]:
    """Steps 1-5 of the module docstring on one line: a row of results.csv."""
    passive_config: Config = ("passive", 0, {})
    p_out, first, last, dt = simulate(seed, passive_config, speed)
    a_out, _, _, _ = simulate(seed, ("line_adaptive", 0, {}), speed)
    masks = [
        position_window(p_out["pantograph_contact_position"][:, k], first, last)
        for k in range(len(PANTOGRAPHS))
    ]

    def filtered(out: np.ndarray) -> list[np.ndarray]:
        return [lowpass(out["pantograph_contact_force"][:, k], dt)[masks[k]] for k in range(len(PANTOGRAPHS))]

    from pac_rig import composition

    values, _ = composition.derive(
        {
            "scenario": "realistic_electromechanical",
            "law": "line_adaptive",
            "line_seed": seed,
            "speed_kmh": speed,
        }
    )
    supports = np.asarray(values["line_supports"])
    f1 = (speed / 3.6) / float(np.mean(np.diff(supports)))
    pattern = a_out["u"] - a_out["force_reference"]
    b = basis(pattern, dt, band_edges(f1, float(values["line_max_frequency"])), segments)
    base = filtered(p_out)
    responses: list[list[np.ndarray]] = [[], []]
    with tempfile.TemporaryDirectory() as folder:
        for bj in b:
            got = filtered(_feedforward(seed, speed, bj, folder)[0])
            for k in range(len(PANTOGRAPHS)):
                responses[k].append(got[k] - base[k])
        quads = [sigma_quadratics(base[k], np.array(responses[k]).T) for k in range(len(PANTOGRAPHS))]
        chosen = best_weights(quads[0], quads[1])
        v = None
        if chosen is not None:
            weighted = sum(xi * bj for xi, bj in zip(chosen[1], b, strict=True))
            v = _measured(*_feedforward(seed, speed, weighted, folder))
    p, a = _measured(p_out, first, last, dt), _measured(a_out, first, last, dt)
    row: dict[str, Any] = {"line_seed": seed, "speed_kmh": speed, "segments": segments, "basis": len(b)}
    for k, name in enumerate(PANTOGRAPHS):
        row[f"passive_{name}_sigma"], row[f"passive_{name}_loss_percent"] = p[k]
        row[f"adaptive_{name}_sigma"], row[f"adaptive_{name}_loss_percent"] = a[k]
    row["lambda"] = chosen[0] if chosen else float("nan")
    for k, name in enumerate(PANTOGRAPHS):
        row[f"predicted_{name}_sigma"] = quads[k].sigma(chosen[1]) if chosen else float("nan")
        row[f"bound_{name}_sigma"], row[f"bound_{name}_loss_percent"] = v[k] if v else (float("nan"),) * 2
    return row


def write_report(rows: list[dict[str, Any]], out: Path) -> str:
    """bound.md: per line and over the lines, the leader's and follower's sigma change against the
    passive pair (line_adaptive leading; the bound, predicted and measured) and the follower's loss."""
    write_results(rows, out)
    table = []
    for speed in sorted({r["speed_kmh"] for r in rows}):
        members = [r for r in rows if r["speed_kmh"] == speed]
        found = [r for r in members if np.isfinite(r["bound_leading_sigma"])]
        cells = []
        for kind in ("adaptive", "predicted", "bound"):
            group = members if kind == "adaptive" else found
            changes = [
                Interval.of(
                    [percent_change(r[f"{kind}_{name}_sigma"], r[f"passive_{name}_sigma"]) for r in group]
                )
                for name in PANTOGRAPHS
            ]
            cells += [
                f"{c.mean:+.1f} [{c.low:+.1f}, {c.high:+.1f}] (worst {c.largest:+.1f})" for c in changes
            ]
            if kind != "predicted":
                more = sum(
                    r[f"{kind}_trailing_loss_percent"] > r["passive_trailing_loss_percent"] for r in group
                )
                loss = stats_lib.fmean(r[f"{kind}_trailing_loss_percent"] for r in group)
                cells.append(f"{loss:.2f} %, {more} of {len(group)}")
        passive_loss = stats_lib.fmean(r["passive_trailing_loss_percent"] for r in members)
        table.append([f"{speed:g}", f"{len(found)} of {len(members)}", f"{passive_loss:.2f} %", *cells])
    header = [
        "v [km/h]",
        "lines with a bound",
        "follower's loss, passive pair",
        "line_adaptive: leader",
        "follower",
        "follower's loss, lines with more",
        "bound predicted: leader",
        "follower",
        "bound run: leader",
        "follower",
        "follower's loss, lines with more",
    ]
    per_line = [
        [
            str(r["line_seed"]),
            f"{r['speed_kmh']:g}",
            f"{r['lambda']:g}",
            f"{percent_change(r['adaptive_leading_sigma'], r['passive_leading_sigma']):+.1f} / "
            f"{percent_change(r['adaptive_trailing_sigma'], r['passive_trailing_sigma']):+.1f}",
            f"{percent_change(r['predicted_leading_sigma'], r['passive_leading_sigma']):+.1f} / "
            f"{percent_change(r['predicted_trailing_sigma'], r['passive_trailing_sigma']):+.1f}",
            f"{percent_change(r['bound_leading_sigma'], r['passive_leading_sigma']):+.1f} / "
            f"{percent_change(r['bound_trailing_sigma'], r['passive_trailing_sigma']):+.1f}",
            f"{r['passive_trailing_loss_percent']:.2f} / {r['adaptive_trailing_loss_percent']:.2f} / "
            f"{r['bound_trailing_loss_percent']:.2f}",
        ]
        for r in rows
    ]
    seeds = sorted({r["line_seed"] for r in rows})
    text = (
        "# A leader's learned feedforward reshaped to spare its follower's sigma\n\n"
        "Generated by `make realistic-pair-bound` (src/pac_experiments/pac_experiments/realistic/"
        "pair_bound.py, whose docstring has the method): the pair's runs (realistic_electromechanical, "
        f"two pantographs 200 m apart on moving roofs, supports 10-30), line seeds {seeds[0]}-{seeds[-1]}, "
        f"{rows[0]['basis']} basis runs per line ({rows[0]['segments']} stretch(es)). The reshaped pattern "
        "('bound') is chosen per line knowing both pantographs' measured responses there (no law knows "
        "them): what a law learning both could reach in this family of patterns, not a limit. sigma change "
        "against the passive pair on the same line: mean [95 % interval] (worst) over the lines.\n\n"
        + markdown.table(header, table)
        + "\n\nPer line (sigma change leader / follower [%]; the follower's contact loss [%]):\n\n"
        + markdown.table(
            [
                "line",
                "v [km/h]",
                "lambda",
                "line_adaptive",
                "bound predicted",
                "bound run",
                "follower's loss: passive / line_adaptive / bound",
            ],
            per_line,
        )
        + "\n"
    )
    (out / "bound.md").write_text(text)
    return text


def _run(args: tuple[int, float, int]) -> dict[str, Any]:
    return run_line(*args)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="realistic_pair_bound", description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=OUT, help="report folder (default: %(default)s)")
    parser.add_argument("--workers", type=int, default=2, help="processes (default 2)")
    parser.add_argument("--seeds", type=int, nargs="+", default=list(SEEDS), help="line seeds")
    parser.add_argument(
        "--speeds", type=float, nargs="+", default=[SPEED], help="km/h (default: %(default)s)"
    )
    parser.add_argument(
        "--segments", type=int, default=SEGMENTS, help="stretches of the run per band (default: %(default)s)"
    )
    args = parser.parse_args(argv)
    if not 1 <= args.segments <= 20:
        print(f"realistic_pair_bound: --segments {args.segments}: allowed 1 to 20", file=sys.stderr)
        return 2
    jobs = [(seed, speed, args.segments) for speed in args.speeds for seed in args.seeds]
    with ProcessPoolExecutor(args.workers) as pool:
        rows = list(pool.map(_run, jobs))
    print(write_report(rows, args.out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
