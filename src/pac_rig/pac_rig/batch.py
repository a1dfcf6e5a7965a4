"""Many offline scenarios in one process: the closed loop of :func:`pac_rig.closed_loop.run`, compiled.

:func:`run_batch` packs N scenarios into arrays (one row per scenario) and runs the
whole tick loop of each in compiled code, groups of scenarios in parallel threads (the compiled loop
releases the GIL).  The loop calls the same compiled core functions as the classes
``Plant``, ``AdaptiveObserver`` and ``BacksteppingController`` do, in the same order,
so every trace equals the one ``closed_loop.run`` gives, bit for bit
(``tests/test_batch.py``).  The backstepping law only: a scenario the batch cannot run
(another law, or the FE line: :func:`batchable`) is refused with a ValueError.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np
from numba import njit

from pac_controller.backstepping import backstepping_law
from pac_controller.controller import limit_command
from pac_controller.reference import reference_args, reference_at
from pac_model import model
from pac_observer.observer import _DIVERGED_REASONS, observer_advance, observer_initial_state, observer_output
from pac_plant.plant import plant_advance, quantise

from .closed_loop import DIVERGENCE_DISPLACEMENT, DIVERGENCE_FORCE, Scenario, build_cores

#: Per-tick traces, rows of ``BatchResult.traces[name]`` (NaN after a divergence).
TRACES = ("contact_force", "force_reference", "u", "stiffness", "stiffness_hat", "z1")
_DISPLACEMENT, _FORCE = 4, 5  # divergence codes after the observer's (1-3)


@njit(cache=True, error_model="numpy")
def _run_one(ticks, delay, plant_f, plant_i, a, theta, z0, noise, obs_consts, obs_init, ctrl_f, ref_f, out):
    """One scenario, ticks 0..ticks-1, into ``out`` (len(TRACES) x ticks); returns (tick, code, value).

    code 0: no divergence; 1-3 the observer's (``_DIVERGED_REASONS``), 4 |z| too large
    (value z1), 5 |u| demanded too large (value u).  The order of operations is that of
    ``closed_loop.run`` and the classes' methods.
    """
    dt, omega, m1, m2, q, noisy = plant_f[0], plant_f[1], plant_f[2], plant_f[3], plant_f[4], plant_f[5]
    substeps, unilateral = plant_i[0], plant_i[1] != 0
    c_omega, c_m1, c_b1, c_k1, c_m2, c_b2 = ctrl_f[0], ctrl_f[1], ctrl_f[2], ctrl_f[3], ctrl_f[4], ctrl_f[5]
    c1, c2, c3, k_min = ctrl_f[6], ctrl_f[7], ctrl_f[8], ctrl_f[9]
    slew, u_min, u_max, fallback, passive = ctrl_f[10], ctrl_f[11], ctrl_f[12], ctrl_f[13], ctrl_f[14] != 0.0
    shape = int(ref_f[0])
    xi0, theta_hat0, s_z0, s_theta0 = obs_init
    state = observer_initial_state(xi0, theta_hat0, s_z0, s_theta0, obs_consts)
    z = z0.copy()
    u_applied = 0.0
    pending = np.zeros(max(delay, 1))  # pending[k % delay]: the command due at tick k + 1
    last_u, last_tick = 0.0, -1
    for k in range(ticks):
        t = k * dt
        # Plant: measurement y_k (eq. (10), plus noise and quantisation) and truth.
        y1, y2 = z[0], z[1]
        if noisy != 0.0:
            y1, y2 = y1 + noise[k, 0], y2 + noise[k, 1]
        y1, y2 = quantise(y1, q), quantise(y2, q)
        stiff = model.stiffness(t, omega, theta)
        force = model.contact_force(stiff, z[0], unilateral)
        if not (abs(y1) < DIVERGENCE_DISPLACEMENT and abs(y2) < DIVERGENCE_DISPLACEMENT):
            return k, _DISPLACEMENT, y1
        # Observer.
        y = np.array([y1, y2])
        if k == 0:
            state = (state[0], state[1], state[2], state[3], state[4], state[5], state[6], y)
        else:
            status, reached, state, _ = observer_advance(k - 1, state, y, 1, u_applied, obs_consts)
            if status:
                return reached, status, math.nan
        z_hat, theta_hat = observer_output(state), state[6]
        # Controller: BacksteppingController.compute.
        f_r = reference_at(t, shape, ref_f[1], ref_f[2], ref_f[3], ref_f[4], ref_f[5])
        if passive:
            u_law = f_r[0]
        elif not (np.isfinite(z_hat).all() and np.isfinite(theta_hat).all()):
            u_law = fallback
        else:
            u_law = backstepping_law(
                t, f_r, z_hat, theta_hat, c_omega, c_m1, c_b1, c_k1, c_m2, c_b2, c1, c2, c3, k_min
            )[0]
            if not math.isfinite(u_law):
                u_law = fallback
        u = limit_command(u_law, last_u, last_tick >= 0, k - last_tick, slew, dt, u_min, u_max)
        last_u, last_tick = u, k
        if not abs(u_law) < DIVERGENCE_FORCE:
            return k, _FORCE, u_law
        out[0, k] = force
        out[1, k] = f_r[0]
        out[2, k] = u
        out[3, k] = stiff
        out[4, k] = model.stiffness(t, omega, theta_hat)
        out[5, k] = z[0]
        # Command delay, then the plant over [t_k, t_k+1].
        if delay == 0:
            u_applied = u
        else:
            u_applied = pending[k % delay]
            pending[k % delay] = u
        z = plant_advance(z, t, dt, substeps, u_applied, a, theta, omega, m1, m2, unilateral)
    return ticks, 0, 0.0


@njit(cache=True, nogil=True)
def _run_rows(
    rows,
    ticks,
    delay,
    plant_f,
    plant_i,
    a,
    theta,
    z0,
    noise,
    consts_f,
    consts_a,
    obs_init_f,
    ctrl_f,
    ref_f,
    out,
    result_tick,
    result_code,
    result_value,
):
    """:func:`_run_one` for the given rows, without the GIL (one thread per group of rows).

    Threads rather than numba's ``parallel=True``: compiled for parallel, the same core
    functions gave results a few ulp apart from the per-tick path's (seen), which would
    break "batch == closed_loop.run bit for bit".
    """
    for i in rows:
        cf, ca = consts_f[i], consts_a[i]
        # (dt, A, C^T Sigma, Sigma, E, Q_h, forgetting, floor input, omega, m1, m2): AdaptiveObserver.consts
        # The observer's own A (the nominal model), not the plant's a[i]: they differ under a mass mismatch.
        consts = (
            cf[0], ca[4].copy(), ca[0, :, :2].copy(), ca[1, :2, :2].copy(), ca[2].copy(), ca[3].copy(),
            cf[1], cf[2], cf[3], cf[4], cf[5],
        )  # fmt: skip
        init = (obs_init_f[i, :4].copy(), obs_init_f[i, 4:7].copy(), obs_init_f[i, 7], obs_init_f[i, 8])
        tk, code, value = _run_one(
            ticks[i], delay[i], plant_f[i], plant_i[i], a[i], theta[i], z0[i], noise[i], consts, init,
            ctrl_f[i], ref_f[i], out[i],
        )  # fmt: skip
        result_tick[i], result_code[i], result_value[i] = tk, code, value


@dataclass(frozen=True)
class BatchResult:
    """Traces of N runs: ``traces[name][i, k]`` is tick k of scenario i (NaN from its divergence on)."""

    traces: dict[str, np.ndarray]
    ticks: np.ndarray  # (N,) ticks run (the scenario's, or the tick it diverged at)
    diverged: list[str | None]  # the closed_loop.DivergenceError reason, None when the run finished
    wall_seconds: float
    sample_period: np.ndarray  # (N,) [s]

    @property
    def simulated_seconds(self) -> float:
        return float(np.sum(self.ticks * self.sample_period))


def _reason(code: int, value: float) -> str | None:
    if code == 0:
        return None
    if code == _DISPLACEMENT:
        return f"|z| exceeded {DIVERGENCE_DISPLACEMENT} m (z1={value:.3g})"
    if code == _FORCE:
        return f"|u| demanded by the law exceeded {DIVERGENCE_FORCE:g} N ({value:.3g} N)"
    return _DIVERGED_REASONS[code]


def pack(scenarios: Sequence[Scenario]) -> tuple:
    """The arrays :func:`_run_rows` takes after ``rows``, one row per scenario (from the cores' set-up)."""
    n = len(scenarios)
    t_max = max(s.loop.ticks for s in scenarios)
    noisy = any(any(v > 0.0 for v in s.plant.noise_std) for s in scenarios)
    ticks = np.array([s.loop.ticks for s in scenarios], dtype=np.int64)
    delay = np.array([s.loop.command_delay_ticks for s in scenarios], dtype=np.int64)
    plant_f, plant_i = np.zeros((n, 6)), np.zeros((n, 2), dtype=np.int64)
    a, theta, z0 = np.zeros((n, 4, 4)), np.zeros((n, 3)), np.zeros((n, 4))
    noise = np.zeros((n, t_max if noisy else 1, 2))
    consts_f, consts_a, obs_init = np.zeros((n, 6)), np.zeros((n, 5, 4, 4)), np.zeros((n, 9))
    ctrl_f, ref_f = np.zeros((n, 15)), np.zeros((n, 6))
    for i, s in enumerate(scenarios):
        plant, observer, controller = build_cores(s)
        if not batchable(s):
            raise ValueError(
                f"scenario {i}: the batch runs the lumped line, observer adaptive, law adaptive_backstepping "
                f"or passive only (catenary_model {s.plant.catenary_model}, observer {s.observer.observer}, "
                f"law {s.controller.effective_law})"
            )
        p, plant_p = s.pantograph, plant.pantograph
        is_noisy = any(v > 0.0 for v in s.plant.noise_std)
        plant_f[i] = (
            plant.sample_period,
            plant._omega,
            plant_p.m1,
            plant_p.m2,
            s.plant.quantisation,
            float(is_noisy),
        )
        plant_i[i] = (s.plant.substeps, int(plant._unilateral))
        a[i], theta[i], z0[i] = plant._a, plant._theta, plant.z
        if is_noisy:
            for k in range(s.loop.ticks):
                noise[i, k] = plant._noise(k)
        c = observer.consts
        consts_f[i] = (c[0], c[6], c[7], c[8], c[9], c[10])
        consts_a[i, 0, :, :2], consts_a[i, 1, :2, :2], consts_a[i, 2], consts_a[i, 3] = c[2], c[3], c[4], c[5]
        consts_a[i, 4] = c[1]
        op = s.observer
        obs_init[i] = (*op.z_hat0, *op.theta_hat0, op.s_z0, op.s_theta0)
        cp = s.controller
        ctrl_f[i] = (
            s.track.omega,
            p.m1,
            p.b1,
            p.k1,
            p.m2,
            p.b2,
            cp.c1,
            cp.c2,
            cp.c3,
            cp.stiffness_hat_min,
            cp.slew_rate_max,
            cp.u_min,
            cp.u_max,
            cp.fallback_force,
            float(cp.effective_law == "passive"),
        )
        ref_f[i] = reference_args(s.reference)
    return ticks, delay, plant_f, plant_i, a, theta, z0, noise, consts_f, consts_a, obs_init, ctrl_f, ref_f


def batchable(s: Scenario) -> bool:
    """What the compiled batch loop runs: the lumped line, the adaptive observer, the adaptive
    backstepping or passive law."""
    return (
        s.plant.catenary_model == "lumped"
        and s.observer.observer == "adaptive"
        and s.controller.effective_law in ("adaptive_backstepping", "passive")
    )


def run_batch(scenarios: Sequence[Scenario], threads: int = 1) -> BatchResult:
    """Run every scenario offline (compiled closed loop), the scenarios shared among ``threads`` threads."""
    if not scenarios:
        raise ValueError("run_batch needs at least one scenario")
    if threads < 1:
        raise ValueError(f"threads must be >= 1, got {threads!r}")
    args = pack(scenarios)
    n = len(scenarios)
    out = np.full((n, len(TRACES), int(args[0].max())), np.nan)
    result_tick, result_code, result_value = (
        np.zeros(n, dtype=np.int64),
        np.zeros(n, dtype=np.int64),
        np.zeros(n),
    )
    # Interleaved groups: neighbouring scenarios often cost alike (e.g. a sweep row).
    groups = [np.arange(g, n, threads, dtype=np.int64) for g in range(min(threads, n))]
    start = time.perf_counter()
    with ThreadPoolExecutor(max_workers=len(groups)) as pool:
        done = [
            pool.submit(_run_rows, rows, *args, out, result_tick, result_code, result_value)
            for rows in groups
        ]
        for future in done:
            future.result()
    wall = time.perf_counter() - start
    return BatchResult(
        traces={name: out[:, j, :] for j, name in enumerate(TRACES)},
        ticks=result_tick,
        diverged=[_reason(int(c), float(v)) for c, v in zip(result_code, result_value, strict=True)],
        wall_seconds=wall,
        sample_period=args[2][:, 0].copy(),
    )
