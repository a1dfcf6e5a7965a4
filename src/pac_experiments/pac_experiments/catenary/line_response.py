"""``ros2 run pac_experiments line_response``: the line's response to a span-periodic command,
measured, and what a law could reach with it known.

line_adaptive (docs/laws.md) learns one complex response D_h per harmonic h of the span
frequency, as if the line were time-invariant: a command at harmonic h moves the force at
harmonic h only.  The FE line is periodic in space, so to the pantograph it is periodic in
time (period T = L / v): a command at h moves the force at every harmonic h +- m.  This tool
measures how much, on the same closed loop the campaigns run (``config/campaigns/fe_laws.yaml``,
the contact-force observer, the rig's limits and delay):

- E_0: the force's span harmonics (over whole spans of the periodic steady state, from the
  *true* contact force) with the feedforward held at zero (passive);
- the real 2H x 2H matrix M = dE / dU by finite differences: one run per real and imaginary
  part of each U_h (``step`` newtons), the law's learning switched off (gain 0, guard off) so
  that U stays what was set.  Real, not complex: a time-varying line maps U_h and conj(U_h)
  to different harmonics;
- its coupling (the share of ||M|| off its 2 x 2 diagonal blocks) and the diagonal |D_h|;
- sigma (EN 50318, 20 Hz) of three feedforwards, each run on the closed loop: the diagonal
  model's fixed point (E_h = 0 harmonic by harmonic, U_h = -E_0h / D_h: the point
  line_adaptive's harmonic-by-harmonic steps head for), the exact inverse of M (E = 0 on every
  harmonic at once), and the regularised least-squares one, U = argmin |E_0 + M U|^2 + mu |U|^2
  (what a law that knew M would command).

The feedforwards are one-shot (no learning on top), so their sigma is what M, measured at
U = 0, predicts on a line that is linear only while contact holds and the limits do not clip.
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pac_common import markdown
from pac_controller.line_adaptive import LineAdaptiveLaw
from pac_controller.line_adaptive_kernels import U_FF
from pac_experiments.campaign.run import en50318_measures
from pac_experiments.campaign.spec import expand, load_spec
from pac_experiments.campaign.summary import percent_change
from pac_experiments.catenary.experiment import SPEC
from pac_rig.batch import prepare
from pac_rig.closed_loop import build_cores
from pac_rig.loop import TICK
from pac_rig.simulate import scenario_from_flat

OUT = Path("reports/catenary/laws/response")
#: Spans run per measurement: the statistics (and E) over spans MEASURED of the periodic steady state.
SPANS = 14
MEASURED = (8, 14)
#: The harmonics measured: up to the EN 50318 low-pass frequency [Hz].
EN50318_BAND = 20.0


@dataclass(frozen=True)
class Run:
    """One closed-loop run with the feedforward held at ``u``."""

    harmonics: np.ndarray  # E_h of the true force over the measured spans (complex, h = 1..H)
    sigma: float  # EN 50318 sigma over the measured spans [N]
    loss: float  # contact loss over the measured spans [fraction]
    u_max: float  # max |u| over the measured spans [N]


class LineResponse:
    """The closed loop of one campaign point, with line_adaptive's feedforward set from outside."""

    def __init__(self, values: dict) -> None:
        values = {**values, "law": "line_adaptive"}
        self.scenario = scenario_from_flat(values)
        _, _, controller = build_cores(self.scenario)
        law = controller.law
        assert isinstance(law, LineAdaptiveLaw)
        self.period, self.count, self.dt = law.period_ticks, law.harmonics, law.dt
        w = 2.0 * math.pi / (self.period * self.dt)
        self.frequencies = np.arange(1, self.count + 1) * w / (2.0 * math.pi)
        # exp(-i h w t) over one span, t from the span's start (the law's phase: tick mod N).
        self._basis = np.exp(
            -1j * np.outer(np.arange(self.period), np.arange(1, self.count + 1)) * w * self.dt
        )

    def run(self, u: np.ndarray) -> Run:
        """The run with U_h = ``u`` (complex, H) from the first tick on, learning off."""
        loop, noise = prepare(0, self.scenario)  # the batch's loop and sensor noise (one row: none)
        loop.controller_params[0]["line_gain"] = 0.0  # the span's step is then U = what was applied
        loop.controller_params[0]["line_guard_ratio"] = math.inf
        n, ticks = self.period, SPANS * self.period
        if 1 < len(noise) < ticks:
            raise ValueError(f"the scenario lasts {len(noise)} ticks; the measurement needs {ticks}")
        out = np.empty(ticks, TICK)
        loop.run(0, 1, noise, out[:1])  # the first command restarts the law, which forgets U
        loop.memory[U_FF] = u
        reached, code, value = loop.run(1, ticks, noise[1:] if len(noise) > 1 else noise, out[1:])
        if code:
            raise RuntimeError(f"the run diverged at tick {reached} (code {code}, {value:.3g})")
        force = out["contact_force"]
        spans = force.reshape(SPANS, n)[MEASURED[0] : MEASURED[1]]
        harmonics = ((2.0 / n) * (spans @ self._basis)).mean(axis=0)
        window = (MEASURED[0] * n * self.dt, MEASURED[1] * n * self.dt)
        m = en50318_measures(
            out["time"], force, out["u"], out["contact_force_hat"], out["contact_uplift"], window, self.dt
        )
        return Run(
            harmonics,
            m["en50318_contact_force_std"],
            m["en50318_contact_loss_percent"] / 100.0,
            float(np.abs(out["u"][n * MEASURED[0] :]).max()),
        )

    def matrix(self, base: Run, step: float) -> np.ndarray:
        """M = dE/dU (real 2H x 2H, [Re; Im] order) by forward differences of ``step`` newtons."""
        h = self.count
        m = np.empty((2 * h, 2 * h))
        for j in range(2 * h):
            u = np.zeros(h, complex)
            u[j % h] = step if j < h else 1j * step
            m[:, j] = (_real(self.run(u).harmonics) - _real(base.harmonics)) / step
        return m


def _real(e: np.ndarray) -> np.ndarray:
    return np.concatenate([e.real, e.imag])


def _complex(x: np.ndarray) -> np.ndarray:
    h = len(x) // 2
    return x[:h] + 1j * x[h:]


def diagonal(m: np.ndarray) -> np.ndarray:
    """D_h, the complex response of harmonic h to U_h (the diagonal model's), from M's real part."""
    h = len(m) // 2
    return np.array([complex(m[i, i], m[h + i, i]) for i in range(h)])


def coupling(m: np.ndarray) -> float:
    """||M off its 2 x 2 diagonal blocks|| / ||M|| (Frobenius): 0 on a time-invariant line."""
    h = len(m) // 2
    off = m.copy()
    for i in range(h):
        off[np.ix_([i, h + i], [i, h + i])] = 0.0
    return float(np.linalg.norm(off) / np.linalg.norm(m))


def regularised(m: np.ndarray, e0: np.ndarray, mu: float) -> np.ndarray:
    """argmin_U |E_0 + M U|^2 + mu |U|^2 (complex U_h)."""
    x = -np.linalg.solve(m.T @ m + mu * np.eye(len(m)), m.T @ _real(e0))
    return _complex(x)


def analyse(speed_kmh: float, mu: float, step: float) -> dict:
    point = next(
        p for p in expand(load_spec(SPEC))
        if p.values["law"] == "line_adaptive" and p.values["speed_kmh"] == speed_kmh
        and "plant_mass_scale" not in p.values and "noise_std" not in p.values
        and "command_delay_ticks" not in p.values
    )  # fmt: skip
    # The whole band the EN 50318 statistics keep, whatever band the law learns.
    line = LineResponse({**point.values, "line_max_frequency": EN50318_BAND})
    base = line.run(np.zeros(line.count, complex))
    m = line.matrix(base, step)
    d = diagonal(m)
    cases = {
        "passive (U = 0)": base,
        "diagonal model's fixed point": line.run(-base.harmonics / d),
        "exact inverse of M": line.run(_complex(-np.linalg.solve(m, _real(base.harmonics)))),
        f"regularised, mu = {mu:g}": line.run(regularised(m, base.harmonics, mu)),
    }
    return {"speed": speed_kmh, "line": line, "matrix": m, "diagonal": d, "cases": cases}


def report(results: list[dict], mu: float, step: float) -> str:
    lines = [
        "# The FE line's response to a span-periodic command",
        "",
        "Generated by `ros2 run pac_experiments line_response` (src/pac_experiments/pac_experiments/"
        "line_response.py; method in its docstring and docs/laws.md). The nominal points of "
        f"config/campaigns/fe_laws.yaml; finite-difference step {step:g} N; statistics over spans "
        f"{MEASURED[0]}-{MEASURED[1]} of {SPANS}, from the true contact force.",
        "",
    ]
    for r in results:
        line, d, base = r["line"], r["diagonal"], r["cases"]["passive (U = 0)"]
        lines += [f"## {r['speed']:g} km/h ({line.count} harmonics of {line.frequencies[0]:.3f} Hz)", ""]
        lines += [
            f"Coupling: {100 * coupling(r['matrix']):.0f} % of ||M|| lies off the harmonic-by-harmonic "
            "blocks (0 on a time-invariant line).",
            "",
            markdown.table(
                ["h", "f [Hz]", "|D_h|", "arg D_h [deg]", "|E_0h| [N]"],
                [
                    [
                        h + 1,
                        f"{line.frequencies[h]:.2f}",
                        f"{abs(d[h]):.3f}",
                        f"{math.degrees(np.angle(d[h])):.0f}",
                        f"{abs(base.harmonics[h]):.1f}",
                    ]
                    for h in range(line.count)
                ],  # fmt: skip
                "rrrrr",
            ),
            "",
            markdown.table(
                ["feedforward", "sigma [N]", "change vs passive", "contact loss", "max abs u [N]"],
                [
                    [
                        name,
                        f"{c.sigma:.2f}",
                        f"{percent_change(c.sigma, base.sigma):+.1f} %",
                        f"{100 * c.loss:.2f} %",
                        f"{c.u_max:.0f}",
                    ]
                    for name, c in r["cases"].items()
                ],  # fmt: skip
                "lrrrr",
            ),
            "",
        ]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="line_response", description=__doc__.split("\n\n")[0])
    ap.add_argument(
        "--speed",
        type=float,
        action="append",
        help="km/h, a nominal point of the campaign (repeatable; default 280 and 300)",
    )
    ap.add_argument(
        "--mu",
        type=float,
        default=0.01,
        help="regularisation of the least-squares feedforward (per N^2 of U)",
    )
    ap.add_argument("--step", type=float, default=20.0, help="finite-difference step [N]")
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args(argv)
    if not (args.mu >= 0.0 and args.step > 0.0):
        print(
            f"line_response: --mu must be >= 0 and --step > 0 (got {args.mu}, {args.step})", file=sys.stderr
        )
        return 2
    results = [analyse(v, args.mu, args.step) for v in (args.speed or [280.0, 300.0])]
    args.out.mkdir(parents=True, exist_ok=True)
    text = report(results, args.mu, args.step)
    (args.out / "response.md").write_text(text + "\n")
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
