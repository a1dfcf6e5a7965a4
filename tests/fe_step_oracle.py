"""The FE step in numpy: the reference the compiled ``step.fe_step`` is tested against.

The same algorithm as ``pac_plant.catenary.integrator`` describes (Newmark average acceleration,
the contact and the slack droppers as Woodbury corrections at the new time level, the active set
iterated until it agrees with its solution), written with dense numpy on the simulation's public
parts only: the line (``sim.line``: M, K, the contact interpolation), the step's constants
(``sim.constants``: the Cholesky factor, the droppers' A^-1 g_j, the pantograph's matrices) and its
state (d, v, a, p, vp, ap, x, the contact flag, the slack set, the counters). It differs from the
compiled step only in how it computes the same numbers (docs/numerics.md, "FE line"): the
right-hand side with M and K, one whole banded solve, A^-1 e_i over the whole line. One pantograph
only (the compiled step runs several).
"""

from __future__ import annotations

import numpy as np

from pac_common import divergence
from pac_common.divergence import OFF_LINE
from pac_plant.catenary import step as compiled_step
from pac_plant.catenary.banded import band_chol_solve
from pac_plant.catenary.integrator import ContactSimulation
from pac_plant.catenary.line import DOFS_PER_NODE
from pac_plant.catenary.newmark import newmark_rhs, newmark_update


class NumpyStep:
    """``NumpyStep(sim)(force)``: one step of ``sim`` in numpy, in place, as ``sim.step(force)``.

    Keeps A^-1 e_i of the last contact elements' DOFs (two new solves per element), as the
    compiled step keeps its contact columns."""

    def __init__(self, sim: ContactSimulation) -> None:
        if len(sim.pantographs) > 1:
            raise NotImplementedError("the numpy step runs one pantograph (the compiled step runs several)")
        self.sim = sim
        self.unit_solutions: dict[int, np.ndarray] = {}
        # A^-1 g_j of every dropper over the whole line (the compiled step keeps them on the nodes
        # around each dropper) and D = G^T A^-1 G from them.
        line, c = sim.line, sim.constants
        g = np.zeros((len(c.dwc), line.n_dof))
        g[np.arange(len(c.dwc)), c.dwm] = 1.0
        g[np.arange(len(c.dwc)), c.dwc] = -1.0
        for col in g:
            band_chol_solve(c.chol, col)
        self.ydrop = np.ascontiguousarray(g.T)  # (n, nd): column j = A^-1 g_j
        self.ddrop = self.ydrop[c.dwm, :] - self.ydrop[c.dwc, :]

    def __call__(self, input_force: float) -> None:
        sim, c = self.sim, self.sim.constants
        line, panto = sim.line, sim.panto
        dt, c0, c1 = sim.dt, sim.c0, sim.c1
        x_new = sim.x + sim.speed * dt
        if sim.endless and x_new > (line.n_periods // 2 + 1) * line.period_length:
            self._shift_window()
            x_new = sim.x + sim.speed * dt
        if x_new > line.length:
            raise ValueError(divergence.reason(OFF_LINE, x_new))
        d, v, a = sim.d, sim.v, sim.a
        n = line.n_dof
        # Line right-hand side: M (c0 d + 4/dt v + a) + C (c1 d + v), C = alpha M + beta K.
        y_l = np.empty(n)
        m_band, k_band = np.ascontiguousarray(line.M.ab), np.ascontiguousarray(line.K.ab)
        newmark_rhs(m_band, k_band, d, v, a, dt, sim.alpha, sim.beta, np.empty(n), np.empty(n), y_l)
        band_chol_solve(c.chol, y_l)
        if len(c.y_rest):
            y_l += c.y_rest
        dofs, nsh = line.contact_interpolation(x_new)
        yc_l = -(self._unit_solution(dofs[0]) * nsh[0])
        for i in range(1, 4):
            yc_l -= self._unit_solution(dofs[i]) * nsh[i]
        # Pantograph.
        fp = np.diag(panto.ground_stiffness) @ sim.roof_rest
        fp[panto.input] += input_force
        p, vp, ap = sim.p.copy(), sim.vp.copy(), sim.ap.copy()
        bp = fp + c.p_mass @ (c0 * p + (4.0 / dt) * vp + ap)
        bp += c.p_damping @ (c1 * p + vp)
        y_p = c.p_ainv @ bp
        yc_p = c.p_ainv[:, panto.head]
        h = panto.head
        ws_x = line.static_height(x_new)
        # Projections on the contact direction g_c and on the dropper directions g_j.
        gc_y = -float(nsh @ y_l[dofs]) + y_p[h]
        gc_yc = -float(nsh @ yc_l[dofs]) + yc_p[h]
        gc_ydrop = -(nsh @ self.ydrop[dofs, :])  # (nd,)
        gd_y = y_l[c.dwm] - y_l[c.dwc]  # (nd,)
        gd_yc = yc_l[c.dwm] - yc_l[c.dwc]  # (nd,)
        contact, slack = sim.in_contact, sim.slack
        passes = 0
        limit = compiled_step.MAX_ACTIVE_SET_PASSES  # read at the call: a test may lower it
        while passes < limit:
            passes += 1
            ns = len(slack)
            if ns == 0:  # the usual case, in scalars: z = (g_c^T y + g_c^T A^-1 g_c r) / cap
                coef = np.zeros(1 if contact else 0)
                if contact:
                    r_c = sim.kp * ws_x
                    coef[0] = r_c - (gc_y + gc_yc * r_c) / (gc_yc + 1.0 / sim.kp)
            else:
                coef = self._woodbury_coefficients(slack, contact, gc_y, gc_yc, gc_ydrop, gd_y, gd_yc, ws_x)
            # Contact penetration and dropper elongations at that solution.
            delta = gc_y - ws_x
            e = c.e0 + gd_y
            if ns:
                delta += float(gc_ydrop[slack] @ coef[:ns])
                e += self.ddrop[:, slack] @ coef[:ns]
            if contact:
                delta += gc_yc * coef[ns]
                e += gd_yc * coef[ns]
            new_contact = bool(delta > 0.0)
            new_slack = np.flatnonzero(e < 0.0)
            consistent = new_contact == contact and np.array_equal(new_slack, slack)
            if consistent or passes == limit:
                if not consistent:  # keep the set the solution was computed for; count it
                    sim.active_set_unconverged += 1
                break
            contact, slack = new_contact, new_slack
        sim.active_set_passes_max = max(sim.active_set_passes_max, passes)
        d_new = y_l
        p_new = y_p.copy()
        if len(slack):
            d_new += self.ydrop[:, slack] @ coef[: len(slack)]
        if contact:
            d_new += yc_l * coef[len(slack)]
            p_new += yc_p * coef[len(slack)]
        newmark_update(d, v, a, d_new, dt)
        ap_new = c0 * (p_new - p) - (4.0 / dt) * vp - ap
        sim.vp = vp + 0.5 * dt * (ap + ap_new)
        sim.ap, sim.p = ap_new, p_new
        sim.x = x_new
        sim.in_contact, sim.slack = contact, slack
        sim.delta = delta if contact else min(delta, 0.0)
        sim.input_force = input_force
        sim.steps += 1

    def _unit_solution(self, i: int) -> np.ndarray:
        """A^-1 e_i over the whole line, kept for the DOFs of the last two contact elements."""
        col = self.unit_solutions.get(int(i))
        if col is None:
            col = np.zeros(self.sim.line.n_dof)
            col[i] = 1.0
            band_chol_solve(self.sim.constants.chol, col)
            if len(self.unit_solutions) >= 8:
                self.unit_solutions.pop(next(iter(self.unit_solutions)))
            self.unit_solutions[int(i)] = col
        return col

    def _woodbury_coefficients(
        self,
        slack: np.ndarray,
        contact: bool,
        gc_y: float,
        gc_yc: float,
        gc_ydrop: np.ndarray,
        gd_y: np.ndarray,
        gd_yc: np.ndarray,
        ws_x: float,
    ) -> np.ndarray:
        """r - z of q = y + Y (r - z), z = cap^-1 U^T (y + Y r), cap = S^-1 + U^T A^-1 U, with
        S^-1 = diag(-1/k_j of the slack droppers, 1/k_p of the contact)."""
        c, kp = self.sim.constants, self.sim.kp
        ns = len(slack)
        m = ns + (1 if contact else 0)
        cap = np.zeros((m, m))
        uy = np.zeros(m)
        r = np.zeros(m)
        cap[:ns, :ns] = self.ddrop[np.ix_(slack, slack)] - np.diag(1.0 / c.kdrop[slack])
        uy[:ns] = gd_y[slack]
        r[:ns] = c.kdrop[slack] * c.e0[slack]
        s_inv = list(-1.0 / c.kdrop[slack])
        if contact:
            cap[ns, ns] = gc_yc + 1.0 / kp
            cap[ns, :ns] = gc_ydrop[slack]
            cap[:ns, ns] = gd_yc[slack]
            uy[ns] = gc_y
            r[ns] = kp * ws_x
            s_inv.append(1.0 / kp)
        return r - np.linalg.solve(cap, uy + (cap - np.diag(s_inv)) @ r)

    def _shift_window(self) -> None:
        """Move the endless window one period forward: the states shift back one period, the new
        period is at rest."""
        sim, line = self.sim, self.sim.line
        s = DOFS_PER_NODE * line.nodes_per_period
        self.unit_solutions.clear()
        for name in ("d", "v", "a"):
            vec = getattr(sim, name)
            vec[:-s] = vec[s:].copy()
            vec[-s:] = 0.0
            vec[line.fixed] = 0.0
        drop_per_span = line.droppers_per_period
        slack = sim.slack
        sim.slack = slack[slack >= drop_per_span] - drop_per_span
        sim.x -= line.period_length
        sim.offset += line.period_length
