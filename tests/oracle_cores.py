"""The numpy implementation of the three cores as it was before they were compiled (numba).

A test oracle only: ``tests/test_compiled.py`` checks the shipped (compiled) cores against
it.  Same algorithms, written with numpy on small arrays and Python callables, copied
from the last pure-Python version (commit 9d7ad1a) together with the model formulas they
used, so that a change to a shipped formula shows up as a disagreement.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import scipy.linalg

from pac_model.parameters import CatenaryParameters, PantographParameters, TrackParameters

OUTPUT_MATRIX = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]])


# -- pac_common.integrate --------------------------------------------------------------
def rk4_step(f: Callable, t: float, x: np.ndarray, h: float) -> np.ndarray:
    k1 = f(t, x)
    k2 = f(t + 0.5 * h, x + (0.5 * h) * k1)
    k3 = f(t + 0.5 * h, x + (0.5 * h) * k2)
    k4 = f(t + h, x + h * k3)
    return x + (h / 6.0) * (k1 + 2.0 * (k2 + k3) + k4)


def rk4_integrate(f: Callable, t0: float, x0: np.ndarray, duration: float, substeps: int) -> np.ndarray:
    h = duration / substeps
    x = x0
    for i in range(substeps):
        x = rk4_step(f, t0 + i * h, x, h)
    return x


# -- pac_model.model -------------------------------------------------------------------
def stiffness_regressor_derivatives(t: float, omega: float, order: int) -> np.ndarray:
    c, s = math.cos(omega * t), math.sin(omega * t)
    cos_cycle, sin_cycle = (c, -s, -c, s), (s, c, -s, -c)
    out = np.zeros((order + 1, 3))
    out[0, 0] = 1.0
    for n in range(order + 1):
        out[n, 1] = omega**n * cos_cycle[n % 4]
        out[n, 2] = omega**n * sin_cycle[n % 4]
    return out


def stiffness(t: float, omega: float, theta: np.ndarray) -> float:
    wt = omega * t
    return float(theta[0] + theta[1] * math.cos(wt) + theta[2] * math.sin(wt))


def state_matrix(p: PantographParameters) -> np.ndarray:
    return np.array(
        [
            [0.0, 0.0, 1.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
            [-p.k1 / p.m1, p.k1 / p.m1, -p.b1 / p.m1, p.b1 / p.m1],
            [p.k1 / p.m2, -p.k1 / p.m2, p.b1 / p.m2, -(p.b1 + p.b2) / p.m2],
        ]
    )


def output_regressor_row(y1: float, t: float, omega: float, p: PantographParameters) -> np.ndarray:
    wt = omega * t
    c = -y1 / p.m1
    return np.array([c, c * math.cos(wt), c * math.sin(wt)])


def contact_force(k: float, z1: float, unilateral: bool) -> float:
    f = k * z1
    return max(f, 0.0) if unilateral else f


def dynamics(z: np.ndarray, u: float, force: float, a: np.ndarray, p: PantographParameters) -> np.ndarray:
    dz = a @ z
    dz[2] -= force / p.m1
    dz[3] += u / p.m2
    return dz


# -- pac_plant.plant (noise and quantisation left out: they did not change) --------------
class OraclePlant:
    def __init__(self, pantograph, track, catenary: CatenaryParameters, substeps, dt, unilateral=False):
        self.p, self.dt, self.substeps = pantograph, dt, substeps
        self._a = state_matrix(pantograph)
        self._theta = catenary.theta
        self._omega = track.omega
        self._unilateral = unilateral
        self.tick = 0
        self.z = np.zeros(4)

    def derivative(self, t: float, z: np.ndarray, u: float) -> np.ndarray:
        k = stiffness(t, self._omega, self._theta)
        force = contact_force(k, z[0], self._unilateral)
        return dynamics(z, u, force, self._a, self.p)

    def advance(self, u: float) -> None:
        t0 = self.tick * self.dt
        self.z = rk4_integrate(lambda t, z: self.derivative(t, z, u), t0, self.z, self.dt, self.substeps)
        self.tick += 1


# -- pac_observer.observer (gap = 1 only) --------------------------------------------------
class OracleObserver:
    def __init__(self, pantograph: PantographParameters, track: TrackParameters, params, sample_period):
        self.pantograph, self.params = pantograph, params
        self.sample_period = dt = sample_period
        self.omega = track.omega
        a = state_matrix(pantograph)
        c = OUTPUT_MATRIX
        sigma = np.diag(params.sigma)
        self._a = a
        self._c_t_sigma = c.T @ sigma
        self._sigma = sigma
        shifted = a + 0.5 * params.rho_z * np.eye(4)
        self._sz_half_map = scipy.linalg.expm(-shifted * (0.5 * dt))
        self._sz_limit = scipy.linalg.solve_continuous_lyapunov(shifted.T, c.T @ sigma @ c)
        self._sz_half_input = self._sz_limit - self._sz_half_map.T @ self._sz_limit @ self._sz_half_map
        self._theta_forgetting = math.exp(-params.rho_theta * dt)
        self._floor_input = (1.0 - self._theta_forgetting) * params.s_theta_floor * np.eye(3)
        p = self.params
        self.tick = -1
        self.theta_hat = np.array(p.theta_hat0, dtype=float)
        self.lam = np.zeros((4, 3))
        self.xi = np.array(p.z_hat0, dtype=float)
        self.s_z = p.s_z0 * np.eye(4)
        self.s_theta = p.s_theta0 * np.eye(3)
        self._gain_now = self._gain(self.s_z)
        self._closed_now = self._closed(self._gain_now)
        self._s_z_settled = False
        self._y_prev = np.zeros(2)

    @property
    def z_hat(self) -> np.ndarray:
        return self.xi + self.lam @ self.theta_hat

    def _closed(self, gain):
        out = self._a.copy()
        out[:, :2] -= gain
        return out

    def _gain(self, s_z):
        return np.linalg.solve(s_z, self._c_t_sigma)

    def update(self, tick: int, y, actuator_force: float) -> None:
        y_now = np.array(y, dtype=float)
        if self.tick < 0:
            self.tick = tick
            self._y_prev = y_now
            return
        assert tick == self.tick + 1
        self._step(y_now, actuator_force)

    def _step(self, y_now, actuator_force):
        tick = self.tick + 1
        dt = self.sample_period
        t0 = self.tick * dt
        if self._s_z_settled:
            s_z_end = self.s_z
            m0 = m_mid = m_end = self._closed_now
            gain0 = gain_mid = gain_end = self._gain_now
        else:
            s_z_mid = self._sz_half_map.T @ self.s_z @ self._sz_half_map + self._sz_half_input
            s_z_end = self._sz_half_map.T @ s_z_mid @ self._sz_half_map + self._sz_half_input
            gain0, gain_mid, gain_end = self._gain_now, self._gain(s_z_mid), self._gain(s_z_end)
            m0, m_mid, m_end = self._closed_now, self._closed(gain_mid), self._closed(gain_end)
        y0 = self._y_prev
        dy = y_now - y0
        phi = np.array([0.0, 0.0, 0.0, actuator_force / self.pantograph.m2])
        x = np.empty((4, 4))
        x[:, 0] = self.xi
        x[:, 1:] = self.lam
        omega, panto = self.omega, self.pantograph
        stage_gains = {0: (m0, gain0), 1: (m_mid, gain_mid), 2: (m_end, gain_end)}

        def f(t, xx):
            frac = (t - t0) / dt
            closed, gain = stage_gains[round(2.0 * frac)]
            y_s = y0 + frac * dy
            out = closed @ xx
            out[:, 0] += phi + gain @ y_s
            out[2, 1:] += output_regressor_row(y_s[0], t, omega, panto)
            return out

        x = rk4_step(f, t0, x, dt)
        xi, lam = x[:, 0], x[:, 1:]
        phi_reg = lam[:2, :]
        weighted = phi_reg.T @ self._sigma
        s_theta = self._theta_forgetting * self.s_theta + dt * (weighted @ phi_reg) + self._floor_input
        innovation = y_now - xi[:2] - phi_reg @ self.theta_hat
        np.linalg.cholesky(s_theta)
        step = np.linalg.solve(s_theta, dt * (weighted @ innovation))
        theta_hat = self.theta_hat + step
        if not self._s_z_settled:
            settled = np.max(np.abs(s_z_end - self.s_z)) <= 1e-13 * np.max(np.abs(s_z_end))
            self.s_z, self._gain_now, self._closed_now, self._s_z_settled = s_z_end, gain_end, m_end, settled
        self.xi, self.lam, self.s_theta, self.theta_hat = xi, lam, s_theta, theta_hat
        self.tick = tick
        self._y_prev = y_now
        return innovation


# -- pac_controller.reference / backstepping -----------------------------------------------
_FORGET_AFTER = 60.0


def filtered_step(tau: float, p: float) -> np.ndarray:
    if tau <= 0.0:
        return np.zeros(4)
    x = p * tau
    e = math.exp(-x)
    s0 = 1.0 - e * (1.0 + x + x * x / 2.0 + x**3 / 6.0)
    s1 = p * e * x**3 / 6.0
    s2 = p * p * e * (x * x / 2.0 - x**3 / 6.0)
    s3 = p**3 * e * (x - x * x + x**3 / 6.0)
    return np.array([s0, s1, s2, s3])


def reference_steps_before(params, t: float) -> list[tuple[float, float]]:
    p = params
    horizon = t - _FORGET_AFTER / p.filter_bandwidth
    if p.shape == "constant":
        steps = [(0.0, p.force_amplitude)]
    elif p.shape == "step":
        steps = [(0.0, p.force_initial), (p.step_time, p.force_amplitude - p.force_initial)]
    else:
        half = 0.5 * p.period
        first = max(0, math.floor(horizon / half))
        last = math.floor(t / half)
        amp = p.force_amplitude
        steps = [(j * half, amp if j % 2 == 0 else -amp) for j in range(first, last + 1)]
        if first > 0 and first % 2 == 1:
            steps.insert(0, (-math.inf, p.force_amplitude))
    return [(ts, size) for ts, size in steps if ts <= t]


def reference_at(params, t: float) -> np.ndarray:
    p = params.filter_bandwidth
    out = np.zeros(4)
    for ts, size in reference_steps_before(params, t):
        if ts == -math.inf:
            out[0] += size
        else:
            out += size * filtered_step(t - ts, p)
    return out


def reciprocal_derivatives(k: np.ndarray) -> np.ndarray:
    k0, k1, k2, k3 = k
    g0 = 1.0 / k0
    g1 = -k1 * g0**2
    g2 = -k2 * g0**2 + 2.0 * k1**2 * g0**3
    g3 = -k3 * g0**2 + 6.0 * k1 * k2 * g0**3 - 6.0 * k1**3 * g0**4
    return np.array([g0, g1, g2, g3])


def product_derivatives(f: np.ndarray, g: np.ndarray) -> np.ndarray:
    return np.array(
        [
            f[0] * g[0],
            f[1] * g[0] + f[0] * g[1],
            f[2] * g[0] + 2.0 * f[1] * g[1] + f[0] * g[2],
            f[3] * g[0] + 3.0 * f[2] * g[1] + 3.0 * f[1] * g[2] + f[0] * g[3],
        ]
    )


def backstepping_law(p: PantographParameters, omega: float, params, t: float, f_r, z_hat, theta_hat):
    """BacksteppingController.law before compilation (params: ControllerParameters)."""
    c1, c2, c3 = params.c1, params.c2, params.c3
    z1, z2, z3, z4 = z_hat
    k = stiffness_regressor_derivatives(t, omega, 3) @ theta_hat
    if k[0] < params.stiffness_hat_min:
        k = np.array([params.stiffness_hat_min, 0.0, 0.0, 0.0])
    r = product_derivatives(f_r, reciprocal_derivatives(k))
    f1 = -(p.k1 / p.m1) * z1 + (p.k1 / p.m1) * z2 - (p.b1 / p.m1) * z3
    f2 = (p.k1 / p.m2) * (z1 - z2) + (p.b1 / p.m2) * z3 - ((p.b1 + p.b2) / p.m2) * z4
    force_term = z1 * k[0] / p.m1
    dz1, dz2 = z3, z4
    dz3 = f1 + (p.b1 / p.m1) * z4 - force_term
    e1 = z1 - r[0]
    alpha1 = r[1] - c1 * e1
    de1 = dz1 - r[1]
    dalpha1 = r[2] - c1 * de1
    e2 = z3 - alpha1
    alpha2 = (p.m1 / p.b1) * (-c2 * e2 - e1 - f1 + force_term + dalpha1)
    e3 = z4 - alpha2
    de2 = dz3 - dalpha1
    df1 = -(p.k1 / p.m1) * dz1 + (p.k1 / p.m1) * dz2 - (p.b1 / p.m1) * dz3
    dforce_term = (dz1 * k[0] + z1 * k[1]) / p.m1
    ddalpha1 = r[3] - c1 * (dz3 - r[2])
    dalpha2 = (p.m1 / p.b1) * (-c2 * de2 - de1 - df1 + dforce_term + ddalpha1)
    u = p.m2 * (-c3 * e3 + dalpha2 - f2 - (p.b1 / p.m1) * e2)
    return u, (e1, e2, e3)


def limited(u: float, last_u: float | None, ticks_since: int, params, sample_period: float) -> float:
    """BacksteppingController._limited's arithmetic before compilation (params: ControllerParameters)."""
    applied = u
    if last_u is not None:
        step = params.slew_rate_max * sample_period * max(1, ticks_since)
        applied = min(max(applied, last_u - step), last_u + step)
    return min(max(applied, params.u_min), params.u_max)


def closed_loop(scenario, ticks: int) -> dict[str, np.ndarray]:
    """The offline closed loop of pac_rig.closed_loop.run on the oracle cores (no faults, no noise)."""
    s = scenario
    dt = s.loop.sample_period
    plant = OraclePlant(
        s.pantograph, s.track, s.catenary, s.plant.substeps, dt, s.plant.contact_model == "unilateral"
    )
    obs = OracleObserver(s.pantograph, s.track, s.observer, dt)
    omega = s.track.omega
    pending = [0.0] * s.loop.command_delay_ticks
    u_applied, last_u = 0.0, None
    out = {"z": [], "z_hat": [], "theta_hat": [], "u": []}
    for tick in range(ticks):
        z = plant.z.copy()
        obs.update(tick, (z[0], z[1]), u_applied)
        t = tick * dt
        f_r = reference_at(s.reference, t)
        z_hat = obs.z_hat
        u_law, _ = backstepping_law(s.pantograph, omega, s.controller, t, f_r, z_hat, obs.theta_hat)
        u = limited(u_law, last_u, 1, s.controller, dt)
        last_u = u
        out["z"].append(z)
        out["z_hat"].append(z_hat)
        out["theta_hat"].append(obs.theta_hat.copy())
        out["u"].append(u)
        pending.append(u)
        u_applied = pending.pop(0)
        plant.advance(u_applied)
    return {k: np.array(v) for k, v in out.items()}
