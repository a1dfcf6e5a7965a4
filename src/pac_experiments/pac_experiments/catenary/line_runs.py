"""The runs of ``make catenary``'s line checks (what runs; ``fe_line_report`` writes it up).

1. statics: achieved vs target pre-sag, dropper lengths, static stiffness along a span;
2. reference runs: the benchmark-like 3-mass pantograph, passive, at 250 and 300 km/h on
   the 10-span section of every shipped catenary preset (start in static equilibrium under
   its uplift at the first interior support, EN 50318 statistics over the middle two spans),
   beside the EN 50318:2002 bands (a *different* reference model) with the distance to each band;
3. numerics: mesh/time-step convergence, penalty stiffness, damping, cost per step;
4. the diagnosis: the paper's 2-DOF pantograph on the endless FE line at 250/300/320/360
   km/h, passive (u = F_r, constant uplift at the EN 50367 target) vs the unchanged adaptive
   observer + backstepping controller (told span_length 55 m and the speed), with positions
   from the fixed datum and from the static wire, and the best fit of the paper's contact
   model: why that law fails on the line. The laws-against-speeds experiment is a campaign
   (config/campaigns/fe_laws.yaml, ``fe_experiment``).
"""

from __future__ import annotations

import dataclasses
import math
import time
from typing import Any

import numpy as np

from pac_common.contact_statistics import contact_statistics, en50367_criteria, target_mean_force
from pac_plant.catenary.catenary_file import DEFAULT, load_catenary, presets
from pac_plant.catenary.data import CatenaryData, NumericalOptions
from pac_plant.catenary.integrator import ContactSimulation
from pac_plant.catenary.line import Line
from pac_plant.catenary.pantographs import load_pantograph

DATA = CatenaryData()
SPAN = DATA.span
#: EN 50318:2002 reference bands (docs/catenary_data.md §1): quantity -> {speed: (low, high)}.
EN50318_BANDS = {
    "contact_force_mean": {250: (110, 120), 300: (110, 120)},
    "contact_force_std": {250: (26, 31), 300: (32, 40)},
    "statistical_max": {250: (190, 210), 300: (210, 230)},
    "statistical_min": {250: (20, 40), 300: (-5, 20)},
    "contact_force_max": {250: (175, 210), 300: (190, 225)},
    "contact_force_min": {250: (50, 75), 300: (30, 55)},
    "support_uplift_mm": {250: (48, 55), 300: (55, 65)},
    "contact_loss_percent": {250: (0, 0), 300: (0, 0)},
}
#: The pantograph of the reference runs (config/pantographs/): pressed by its uplift, static + aerodynamic
#: = the EN 50367 target Fm(v) (``target_mean_force``).
REFERENCE_PANTOGRAPH = "three_mass"
#: Speeds of the reference runs (those of the EN 50318:2002 bands) [km/h].
REFERENCE_SPEEDS = (250, 300)
EXPERIMENT_SPEEDS = (250, 300, 320, 360)
EXPERIMENT_DURATION = 8.0  # s
EXPERIMENT_WINDOW = (3.0, 8.0)  # s: after the observer's convergence transient
#: (mode, fe_datum) of each experiment run; a passive run's physics does not depend on the datum
#: (u = F_r), only what its observer sees does.
EXPERIMENT_RUNS = (
    ("passive", "fixed"),
    ("passive", "static_wire"),
    ("active", "fixed"),
    ("active", "static_wire"),
)


#: Variants of the 300 km/h passive reference run: label -> passive_reference keywords.
NUMERICS_VARIANTS: dict[str, dict[str, Any]] = {
    "h=1.0 dt=2ms": {"element_size": 1.0, "dt": 2e-3},
    "h=0.5 dt=1ms (default)": {},
    "h=0.25 dt=0.5ms": {"element_size": 0.25, "dt": 5e-4},
    "h=0.25 dt=1ms": {"element_size": 0.25},
    "h=0.5 dt=0.5ms": {"dt": 5e-4},
    "kp=25 kN/m": {"contact_stiffness": 25e3},
    "kp=100 kN/m": {"contact_stiffness": 100e3},
    "kp=200 kN/m": {"contact_stiffness": 200e3},
    "no damping": {"damping": False},
    "static force 120 N": {"force": 120.0},
}


def band_distance(value: float, band: tuple[float, float]) -> float:
    """0 inside the band, else the signed distance to its nearest edge."""
    low, high = band
    return 0.0 if low <= value <= high else (value - high if value > high else value - low)


def reference_lines() -> list[str]:
    """The catenaries of the reference runs: the default line first, then every other preset."""
    return [DEFAULT] + [name for name in presets() if name != DEFAULT]


# -- reference runs (3-mass pantograph, fixed 10-span line) ------------------------------------
def passive_reference(
    speed_kmh: float,
    element_size: float = 0.5,
    dt: float = 1e-3,
    contact_stiffness: float = 50e3,
    damping: bool = True,
    force: float | None = None,
    catenary: str = DEFAULT,
) -> dict[str, Any]:
    """One passive run over the ``catenary`` file's fixed section; statistics over spans 5-6.

    The line's own damping comes from its file; ``element_size`` and ``contact_stiffness``
    replace the file's (the numerics study varies them). Spans 5 and 6 are whole spans, support
    to support (EN 50318 practice), whatever their lengths.
    """
    cat = load_catenary(catenary)
    numerics = dataclasses.replace(
        cat.numerics, element_size=element_size, contact_stiffness=contact_stiffness
    )
    line = Line(cat.data, numerics)
    v = speed_kmh / 3.6
    pantograph, chain = load_pantograph(REFERENCE_PANTOGRAPH)
    force = chain.uplift(speed_kmh) if force is None else force
    support_x = line.layout.support_x
    sim = ContactSimulation(line, pantograph, dt, v, float(support_x[1]), damping=damping)
    sim.start_static(force)
    x_from, x_to = float(support_x[4]), float(support_x[6])
    supports = (x_from, float(support_x[5]), x_to)
    # Half a span past the window's end (the end of the run) and one span either side of it (where
    # the support uplift is watched): the last window span's length.
    tail = float(support_x[6] - support_x[5])
    xs, fs, ups, slack = [], [], [], 0
    support_uplift = 0.0
    start = time.process_time()
    while sim.x + v * dt < x_to + 0.5 * tail:
        sim.step(force)
        xs.append(sim.x)
        fs.append(sim.contact_force)
        ups.append(sim.uplift())
        slack = max(slack, len(sim.slack))
        if x_from - tail < sim.x < x_to + tail:
            support_uplift = max(support_uplift, max(sim.uplift(s) for s in supports))
    wall = time.process_time() - start
    x, f = np.array(xs), np.array(fs)
    stats = contact_statistics(f, x, dt, x_from, x_to)
    return {
        "catenary": cat.data.name,
        "span_lengths_m": sorted({s.length for s in cat.data.spans}),
        "stitched": cat.data.stitched,
        "contact_tension_N": cat.data.contact.tension,
        "messenger_tension_N": cat.data.messenger.tension,
        "speed_kmh": speed_kmh,
        "static_force": force,
        "element_size": element_size,
        "dt": dt,
        "contact_stiffness": contact_stiffness,
        "damping": damping,
        **stats.as_dict(),
        "support_uplift_mm": 1e3 * support_uplift,
        "max_slack_droppers": slack,
        "active_set_passes_max": sim.active_set_passes_max,
        "active_set_unconverged_steps": sim.active_set_unconverged,
        "steps": len(fs),
        "us_per_step": 1e6 * wall / len(fs),
        "_x": x,
        "_f": f,
        "_uplift": np.array(ups),
        "_window_supports": supports,
    }


# -- the experiment (paper's pantograph, closed loop, endless line) ---------------------------
def closed_loop_run(job: tuple[float, str, str]) -> dict[str, Any]:
    from pac_rig.closed_loop import DivergenceError, run
    from pac_rig.simulate import scenario_from_flat

    speed, mode, datum = job
    force = target_mean_force(speed)
    scenario = scenario_from_flat(
        {
            "catenary_model": "fe",
            "fe_datum": datum,
            "speed_kmh": float(speed),
            "span_length": SPAN,
            "duration": EXPERIMENT_DURATION,
            "force_amplitude": force,
            "mode": mode,
            "theta_hat0": (3000.0, 0.0, 0.0),
        }
    )
    cols: dict[str, list[float]] = {k: [] for k in ("t", "x", "F", "k", "k_hat", "u", "uplift", "z1", "F_r")}
    diverged = None
    start = time.process_time()
    try:
        for rec in run(scenario):
            tr = rec.truth
            cols["t"].append(tr.time)
            cols["x"].append(tr.contact_position)
            cols["F"].append(tr.contact_force)
            cols["k"].append(tr.stiffness)
            cols["k_hat"].append(rec.estimate.stiffness_hat)
            cols["u"].append(rec.command.u)
            cols["uplift"].append(tr.contact_uplift)
            cols["z1"].append(tr.z[0])
            cols["F_r"].append(rec.command.force_reference)
    except DivergenceError as exc:
        diverged = str(exc)
    wall = time.process_time() - start
    arrays = {k: np.array(v) for k, v in cols.items()}
    return {
        "speed_kmh": speed,
        "mode": mode,
        "datum": datum,
        "force": force,
        "diverged": diverged,
        "wall": wall,
        **arrays,
    }


def model_fit(r: dict[str, Any]) -> dict[str, float]:
    """Best fit of the paper's contact model F = (th0 + th1 cos wt + th2 sin wt) z1 (eqs. 6-9) to a run.

    Least squares over the window, w = 2 pi v / 55 m: the best any estimate of theta can do.
    ``unexplained_percent`` = RMS(F - fit) / std(F): what no k(t) of eq. (7) can explain.
    """
    t = r["t"]
    w = (t >= EXPERIMENT_WINDOW[0]) & (t <= EXPERIMENT_WINDOW[1])
    omega = 2 * math.pi * r["speed_kmh"] / 3.6 / SPAN
    z1, f, tw = r["z1"][w], r["F"][w], t[w]
    phi = np.column_stack([z1, z1 * np.cos(omega * tw), z1 * np.sin(omega * tw)])
    theta, *_ = np.linalg.lstsq(phi, f, rcond=None)
    resid = f - phi @ theta
    return {
        "fit_k0": float(theta[0]),
        "fit_alpha": float(math.hypot(theta[1], theta[2]) / theta[0]) if theta[0] else math.nan,
        "fit_unexplained_percent": float(100 * np.sqrt(np.mean(resid**2)) / np.std(f)),
        "z1_min_mm": float(1e3 * z1.min()),
        "z1_max_mm": float(1e3 * z1.max()),
    }


def experiment_metrics(r: dict[str, Any], dt: float = 1e-3) -> dict[str, Any]:
    t = r["t"]
    w = (t >= EXPERIMENT_WINDOW[0]) & (t <= EXPERIMENT_WINDOW[1])
    end = float(t[-1]) if len(t) else 0.0
    if r["diverged"] and end < EXPERIMENT_WINDOW[1] - 0.5:
        # Stopped by the closed loop's divergence guard before the window was (mostly) run.
        return {
            "speed_kmh": r["speed_kmh"],
            "mode": r["mode"],
            "datum": r["datum"],
            "target_Fm": r["force"],
            "diverged": r["diverged"],
            "stopped_at_s": end,
            "max_abs_u": float(np.max(np.abs(r["u"]))) if len(t) else None,
        }
    stats = contact_statistics(r["F"], t, dt, *EXPERIMENT_WINDOW)
    verdict = en50367_criteria(stats.contact_force_mean, stats.contact_force_std)
    u = r["u"][w]
    k, kh = r["k"][w], r["k_hat"][w]
    corr = float(np.corrcoef(k, kh)[0, 1]) if np.std(kh) > 0 and np.std(k) > 0 else 0.0
    return {
        "speed_kmh": r["speed_kmh"],
        "mode": r["mode"],
        "datum": r["datum"],
        "target_Fm": r["force"],
        **(model_fit(r) if r["mode"] == "passive" else {}),
        **stats.as_dict(),
        "quality_sigma_le_0.3Fm": verdict.sigma_ok,
        "quality_Fm_minus_3sigma_gt_0": verdict.statistical_min_ok,
        "max_abs_u": float(np.max(np.abs(u))),
        "max_abs_du_dt": float(np.max(np.abs(np.diff(u))) / dt),
        "k_fe_mean": float(np.mean(k)),
        "k_fe_min": float(np.min(k)),
        "k_fe_max": float(np.max(k)),
        "k_hat_mean": float(np.mean(kh)),
        "k_hat_min": float(np.min(kh)),
        "k_hat_max": float(np.max(kh)),
        "k_hat_vs_k_fe_correlation": corr,
        "contact_uplift_max_mm": 1e3 * float(np.max(r["uplift"][w])),
        "wall_s_per_sim_s": r["wall"] / max(t[-1], 1e-9),
        "diverged": r["diverged"],
    }


# -- numerics: cost per step ---------------------------------------------------------------------
def cost_breakdown(n_steps: int = 2000) -> dict[str, float]:
    """Microseconds per 1 kHz step of the 10-span line + 3-mass pantograph at 300 km/h, by part."""
    from pac_plant.catenary.banded import band_chol_solve, band_matvec2

    line = Line(DATA, NumericalOptions())
    sim = ContactSimulation(line, load_pantograph(REFERENCE_PANTOGRAPH)[0], 1e-3, 300 / 3.6, SPAN)
    sim.start_static(157.3)
    for _ in range(200):
        sim.step(157.3)

    def per_call(fn, n=n_steps) -> float:
        t0 = time.process_time()
        for _ in range(n):
            fn()
        return 1e6 * (time.process_time() - t0) / n

    x = np.random.default_rng(0).standard_normal(line.n_dof)
    out = np.empty(line.n_dof)
    total = per_call(lambda: sim.step(157.3))
    # The rig's plant: FEPlant (paper's pantograph, endless window) per 1 kHz tick as plant_node
    # and closed_loop call it: advance + measurement + truth.
    from pac_model.parameters import PantographParameters, TrackParameters
    from pac_plant.fe_plant import FEPlant
    from pac_plant.parameters import PlantOptions

    plant = FEPlant(
        PantographParameters(),
        TrackParameters(speed_kmh=300.0),
        None,
        PlantOptions(catenary_model="fe"),
        1e-3,
    )
    for _ in range(500):
        plant.advance(157.3)

    def tick() -> None:
        plant.advance(157.3)
        plant.measurement()
        plant.truth()

    fe_tick = per_call(tick)
    m_band, k_band, factor = sim.bands
    return {
        "n_dof": line.n_dof,
        "step_total_us": total,
        "fe_plant_tick_us": fe_tick,
        "fe_plant_realtime_factor": 1e3 / fe_tick,
        "fused_matvec_us": per_call(lambda: band_matvec2(m_band, x, k_band, x, out)),
        "banded_solve_us": per_call(lambda: band_chol_solve(factor, out)),
        "contact_lookup_us": per_call(lambda: line.contact_interpolation(100.3)),
    }


def statics_summary() -> tuple[dict[str, Any], Line]:
    line = Line(DATA, NumericalOptions())
    dr = line.droppers
    achieved = -line.w_static[dr.wc]
    mid = slice(36, 45)  # droppers of span 5
    xs = np.linspace(4 * SPAN, 6 * SPAN, 441)
    k = line.static_stiffness(xs)
    return {
        "presag_target_mm": (1e3 * dr.target_sag[mid]).round(3).tolist(),
        "presag_achieved_mm": (1e3 * achieved[mid]).round(4).tolist(),
        "presag_max_error_mm_all_droppers": float(1e3 * np.max(np.abs(achieved - dr.target_sag))),
        "dropper_unstrained_length_m": dr.length0[mid].round(4).tolist(),
        "dropper_static_tension_N": dr.static_tension[mid].round(2).tolist(),
        "contact_wire_height_at_support_mm": float(1e3 * line.w_static[4 * line.support_nodes[4]]),
        "stiffness_at_support_N_per_m": float(line.static_stiffness(np.array([5 * SPAN]))[0]),
        "stiffness_mid_span_N_per_m": float(line.static_stiffness(np.array([5.5 * SPAN]))[0]),
        "stiffness_min_N_per_m": float(k.min()),
        "stiffness_max_N_per_m": float(k.max()),
        "stiffness_estimate_4(Tc+Tm)/L": 4 * (DATA.contact.tension + DATA.messenger.tension) / SPAN,
        "n_dof": line.n_dof,
        "_xs": xs,
        "_k": k,
    }, line


def sigma_reductions(metrics: list[dict[str, Any]]) -> None:
    """Add each active run's sigma reduction vs the passive run (fixed datum) at its speed, in %."""
    by = {(m["speed_kmh"], m["mode"], m["datum"]): m for m in metrics}
    for v in EXPERIMENT_SPEEDS:
        p = by[(v, "passive", "fixed")]
        for datum in ("fixed", "static_wire"):
            a = by[(v, "active", datum)]
            if "contact_force_std" in p and "contact_force_std" in a:
                a["sigma_reduction_percent"] = (
                    100.0 * (p["contact_force_std"] - a["contact_force_std"]) / p["contact_force_std"]
                )
