"""Time integration of line + pantograph: Newmark average acceleration, factorised once.

Unknowns: d, the line's deviation from its static equilibrium (``Line.w_static``), and
p, the pantograph's heights. Both parts are linear and constant,

    M d'' + C d' + K d = f_contact + f_slack,     Mp p'' + Cp p' + Kp p = f_input + f_roof - F e_head,

with Rayleigh damping C = alpha M + beta K on the line. Newmark's average-acceleration
rule (trapezoidal: unconditionally stable, no numerical damping, energy-conserving for
a linear system) turns each step into A q = b with the constant A = K + 4/dt^2 M + 2/dt C
(banded Cholesky once, ``banded.band_chol_solve``) for the line and a small dense inverse
for the pantograph. The two non-smooth parts are low-rank corrections of A, solved exactly
with the Woodbury identity at the new time level (implicit, no refactorisation):

* the moving unilateral penalty contact, F = k_p delta when the penetration
  delta = z_head - w_c(x) > 0 (w_c by the element's Hermite shape functions at the
  contact point): A + k_p g g^T with g = (-N(x) on the line, +1 on the head); A^-1 g
  from A^-1 e_i of the contact element's four DOFs (two solves per new node, cached);
* slack droppers (elongation e_j = e0_j + w_m - w_c < 0): A - k_j g_j g_j^T and the
  static dropper force k_j e0_j removed, A^-1 g_j precomputed for every dropper.

The active set (contact on/off, which droppers are slack) is iterated until it agrees
with the solution it produces (a few passes at most; usually the first one).

``step`` runs all of it compiled (``step.fe_step`` on the explicit arrays
``constants``/``state``); the same algorithm in numpy is the tests' reference
(``tests/fe_step_oracle.py``). The compiled step's kernels differ from the
reference's only in how they compute the same numbers (docs/numerics.md, "FE line"): the
right-hand side with M alone, the solve as eight overlapping chunks side by side in vector
lanes, A^-1 e_i and A^-1 g_j stored on the 20 nodes around i (the rest is below 1e-19 and
1e-18 of the peak).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from pac_common import divergence
from pac_common.divergence import OFF_LINE
from pac_model.parameters import positive_period

from .banded import (
    KD,
    band_chol_solve,
    band_chol_solve_columns,
    band_matvec2,
    chol_factor,
    chunk_factor,
    pad_band,
)
from .line import DOFS_PER_NODE, Line
from .packing import CONSTANT_KINDS, STATE_KINDS, fe_advance_packed, pack
from .pantographs import LumpedPantograph
from .step import (
    DELTA,
    IN_CONTACT,
    INPUT_FORCE,
    N_SLACK,
    OFFSET,
    PASSES_MAX,
    STEP_OK,
    STEPS,
    UNCONVERGED,
    UNIT_REACH,
    WINDOW,
    StepConstants,
    StepState,
    X,
    contact_readings,
    pantograph_contact,
    prepare_unit_patches,
    readings_at,
    unit_start,
)
from .window import line_windows, no_windows


@dataclass(frozen=True)
class PassivePantograph:
    """A pantograph that runs ``lag`` [m] behind the reference point x (0: at it) with the constant
    ``uplift`` [N] on its input DOF (a passive pantograph: no actuator)."""

    pantograph: LumpedPantograph
    lag: float
    uplift: float


def rear_periods(period: float, lag: float) -> int:
    """Periods (of ``period`` [m]) an endless window needs behind the one-pantograph window so that a
    pantograph ``lag`` [m] behind x is as far from the window's rear end as x is in that window."""
    return math.ceil(lag / period - 1e-9) if lag > 0.0 else 0


def block_diagonal(blocks: Sequence[np.ndarray]) -> np.ndarray:
    """The square blocks along the diagonal of one matrix, zero elsewhere (each pantograph's own)."""
    out = np.zeros((sum(len(b) for b in blocks),) * 2)
    at = 0
    for b in blocks:
        out[at : at + len(b), at : at + len(b)] = b
        at += len(b)
    return out


#: Dropper columns A^-1 g_j solved side by side at set-up (``banded.band_chol_solve_columns``).
DROPPER_BLOCK = 64


def dropper_coupling(patches: np.ndarray, lo: np.ndarray, wc: np.ndarray, wm: np.ndarray) -> np.ndarray:
    """D = G^T A^-1 G, D[i, j] = (A^-1 g_j)[wm_i] - (A^-1 g_j)[wc_i], from each column's patch
    ``patches[j]`` on the rows ``lo[j]`` + 0..width-1 (zero where dropper i lies outside it: both
    its DOFs sit on one node, so both are inside or both outside)."""
    nd, width = patches.shape
    coupling = np.zeros((nd, nd))
    for j in range(nd):
        upper, lower = wm - lo[j], wc - lo[j]
        inside = (lower >= 0) & (lower < width)
        coupling[inside, j] = patches[j, upper[inside]] - patches[j, lower[inside]]
    return coupling


class ContactSimulation:
    """Line + pantograph moving at ``speed`` [m/s] from ``x0`` [m], time step ``dt`` [s].

    ``endless``: the line is a moving window: whenever the contact point passes the
    middle of the window by one span, every state vector is shifted back by one span
    (the matrices are span-periodic, so nothing is refactorised) and the new last span
    starts at rest in static equilibrium. ``position`` is then the distance travelled.

    Several pantographs: ``pantograph`` (the controlled one: ``step``'s input force acts on it)
    touches the wire ``lag`` [m] behind the reference point x, each of ``passive`` its own ``lag``
    behind x with its constant uplift. They move together; each has its own contact (contact 0 is
    the controlled one, contact k the passive k - 1) and sees the waves the others leave. On an
    endless line the window shifts when x passes the middle of the part of the window in front of
    ``rear_periods`` (the periods added behind for the largest lag, or for ``window_lag``): every
    contact point then keeps at least the one-pantograph window's distance to the rear end, x the
    same distance ahead.

    ``window_spans`` (0: none) on a line that is not endless: each step works on the spans around
    the pantographs only, ``window_spans`` mean spans plus the largest lag, and holds the rest of
    the line at rest (``window``).
    """

    def __init__(
        self,
        line: Line,
        pantograph: LumpedPantograph,
        dt: float,
        speed: float,
        x0: float,
        *,
        damping: bool = True,
        endless: bool = False,
        lag: float = 0.0,
        passive: Sequence[PassivePantograph] = (),
        window_lag: float | None = None,
        window_spans: float = 0.0,
    ) -> None:
        positive_period(dt, "dt")
        lags = [float(lag)] + [float(q.lag) for q in passive]
        if not all(math.isfinite(q) and q >= 0.0 for q in lags):
            raise ValueError(f"pantograph lags must be finite and >= 0 m, got {lags}")
        if x0 - max(lags) < 0.0:
            raise ValueError(f"a pantograph {max(lags)} m behind x0 = {x0} m starts off the line")
        self.line = line
        self.panto = pantograph
        self.passive = tuple(passive)
        self.pantographs = (pantograph,) + tuple(q.pantograph for q in passive)
        self.lags = np.array(lags)
        # Each pantograph's DOFs in the stacked pantograph vector: the controlled one's first.
        sizes = [q.n for q in self.pantographs]
        self.dof_start = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int64)
        heads = self.dof_start + np.array([q.head for q in self.pantographs], dtype=np.int64)
        inputs = self.dof_start + np.array([q.input for q in self.pantographs], dtype=np.int64)
        self.uplifts = np.array([0.0] + [float(q.uplift) for q in passive])
        # A line of tension sections: each pantograph has a contact on either wire set (an
        # overlap's two wires), the second one without an input of its own (step.StepConstants).
        n_pantographs = len(self.pantographs)
        wires = min(2, len(line.sections))
        n_contacts = wires * n_pantographs
        contact_heads = np.tile(heads, wires)
        contact_inputs = np.concatenate([inputs, np.full((wires - 1) * n_pantographs, -1, dtype=np.int64)])
        self.dt = dt
        self.speed = speed
        self.kp = line.options.contact_stiffness
        self.alpha = line.options.rayleigh_alpha if damping else 0.0
        self.beta = line.options.rayleigh_beta if damping else 0.0
        self.endless = endless
        n = line.n_dof
        self.c0, self.c1 = 4.0 / dt**2, 2.0 / dt
        a_line = line.K.ab * (1.0 + self.c1 * self.beta) + line.M.ab * (self.c0 + self.c1 * self.alpha)
        self._chol = chol_factor(a_line)
        self._m, self._k = np.ascontiguousarray(line.M.ab), np.ascontiguousarray(line.K.ab)
        if n_contacts == 1:
            ground = pantograph.ground_stiffness
            pm = np.diag(pantograph.mass)
            self._pk = pantograph.stiffness + np.diag(pantograph.ground_stiffness)
            self._pc = pantograph.damping if damping else np.zeros_like(pantograph.damping)
            self._pstiff = pantograph.stiffness
        else:
            ground = np.concatenate([q.ground_stiffness for q in self.pantographs])
            pm = np.diag(np.concatenate([q.mass for q in self.pantographs]))
            self._pstiff = block_diagonal([q.stiffness for q in self.pantographs])
            self._pk = self._pstiff + np.diag(ground)
            self._pc = block_diagonal([q.damping for q in self.pantographs])
            if not damping:
                self._pc = np.zeros_like(self._pc)
        self._pground = np.asarray(ground, dtype=float)
        self._pm = pm
        self._ap_inv = np.linalg.inv(self._pk + self.c0 * pm + self.c1 * self._pc)
        # Droppers: A^-1 g_j (line part only) on the UNIT_REACH nodes around dropper j, like the
        # contact columns (the rest is < 1e-18 of the peak: the whole columns, n x nd, were ~100 MB
        # on a 3 km line), and D = G^T A^-1 G from them.
        dr = line.droppers
        self._dwc, self._dwm = dr.wc, dr.wm
        nd = len(dr.node)
        width = min(n, 4 * (2 * UNIT_REACH + 1))
        drop_patches = np.empty((nd, width))
        drop_lo = np.array([unit_start(n, width, int(node)) for node in dr.node], dtype=np.int64)
        for first in range(0, nd, DROPPER_BLOCK):  # (a block of columns at a time: 13 MB on 3 km)
            block = np.arange(first, min(nd, first + DROPPER_BLOCK))
            cols = np.zeros((n, len(block)))
            cols[dr.wm[block], np.arange(len(block))] = 1.0
            cols[dr.wc[block], np.arange(len(block))] = -1.0
            loads = np.concatenate([dr.wc[block], dr.wm[block]])
            band_chol_solve_columns(self._chol, cols, int(loads.min()), int(drop_lo[block].min()))
            for c, j in enumerate(block):
                drop_patches[j] = cols[drop_lo[j] : drop_lo[j] + width, c]
        self._ddrop = dropper_coupling(drop_patches, drop_lo, dr.wc, dr.wm)
        self._kdrop = dr.stiffness.copy()
        self._e0 = dr.elongation0.copy()
        # The window shifts by whole periods of the line (one span where the spans are equal).
        self._drop_per_span = line.droppers_per_period
        span = line.period_length
        rear = rear_periods(span, float(self.lags.max()) if window_lag is None else window_lag)
        self.shift_at = ((line.n_periods - rear) // 2 + 1 + rear) * span
        factors, starts, bounds = chunk_factor(a_line)
        if window_spans > 0.0:
            if endless:
                raise ValueError("a moving window is for a whole line, not an endless one")
            windows = line_windows(line, a_line, self._m, window_spans, float(self.lags.max()))
        else:
            windows = no_windows(factors.shape[2], KD)
        self.constants = StepConstants(
            m_pad=pad_band(self._m),
            chol=self._chol,
            chunk_factors=factors,
            chunk_starts=starts,
            chunk_bounds=bounds,
            x_nodes=np.ascontiguousarray(line.x),
            w_static=np.ascontiguousarray(line.w_static),
            ydrop_patches=drop_patches,
            ddrop=self._ddrop,
            kdrop=self._kdrop,
            e0=self._e0,
            dwc=np.ascontiguousarray(self._dwc, dtype=np.int64),
            dwm=np.ascontiguousarray(self._dwm, dtype=np.int64),
            fixed=np.ascontiguousarray(line.fixed, dtype=np.int64),
            p_mass=np.ascontiguousarray(pm),
            p_damping=np.ascontiguousarray(self._pc, dtype=float),
            p_ainv=np.ascontiguousarray(self._ap_inv),
            p_ground=np.ascontiguousarray(self._pground),
            numbers=np.array(
                [
                    dt,
                    speed,
                    self.alpha,
                    self.beta,
                    self.kp,
                    self.c0,
                    self.c1,
                    line.length,
                    span,
                    self.shift_at,
                ]
            ),
            indices=np.array(
                [
                    pantograph.head,
                    pantograph.input,
                    int(endless),
                    DOFS_PER_NODE * line.nodes_per_period,
                    self._drop_per_span,
                    0,  # the controlled contact
                    n_pantographs,
                ],
                dtype=np.int64,
            ),
            p_heads=contact_heads,
            p_inputs=contact_inputs,
            p_lag=np.tile(self.lags, wires),
            p_uplift=np.tile(self.uplifts, wires),
            y_rest=self._rest_solution(),
            sections=np.ascontiguousarray(line.sections, dtype=np.int64),
            section_x=np.ascontiguousarray(line.section_x, dtype=float),
            lift=np.ascontiguousarray(line.lift, dtype=float),
            p_wire=np.repeat(np.arange(wires, dtype=np.int64), n_pantographs),
            window_x=windows.x_leave,
            window_rows=windows.rows,
            window_drops=windows.drops,
            window_mass=windows.mass,
            window_factors=windows.factors,
            window_starts=windows.starts,
            window_bounds=windows.bounds,
        )
        # State: the arrays the compiled step mutates in place (the attributes below are views).
        self.state = StepState(
            d=np.zeros(n),
            v=np.zeros(n),
            a=np.zeros(n),
            p=np.zeros(len(pm)),
            vp=np.zeros(len(pm)),
            ap=np.zeros(len(pm)),
            roof_rest=np.zeros(len(pm)),
            scalars=np.zeros(4),
            counters=np.array([0, 0, 0, 0, 0, 0, 0, -1], dtype=np.int64),
            slack=np.zeros(nd, dtype=np.int64),
            unit_patches=np.zeros((line.n_nodes, 2, width)),
            unit_ready=np.zeros(line.n_nodes, dtype=np.int64),
            work=np.zeros((1 + n_contacts, n)),
            padded=np.zeros((2, n + 2 * KD)),
            chunk_work=np.zeros((factors.shape[0], factors.shape[2])),
            deltas=np.zeros(n_contacts),
            touching=np.zeros(n_contacts, dtype=np.int64),
            yc_range=np.zeros((n_contacts, 2), dtype=np.int64),
            base_force=np.zeros(n_contacts),
        )
        # One flat float and one int buffer each: a call from Python then types 10 arguments, not 38.
        self._cf, self._ci, self._cl, views = pack(tuple(self.constants), CONSTANT_KINDS)
        self.constants = StepConstants(*views)
        self._sf, self._si, self._sl, views = pack(tuple(self.state), STATE_KINDS)
        self.state = StepState(*views)
        self._packed = (self._cf, self._ci, self._cl, self._sf, self._si, self._sl)
        self._no_flex, self._no_readings = np.zeros((0, 4, 4)), np.zeros(0)
        self.x = float(x0)
        self._zero = np.zeros(n)
        self.start_touching()

    def _rest_solution(self) -> np.ndarray:
        """A^-1 of the line's constant rest load (droppers slack at rest), added to every step's
        solution; empty where every dropper hangs taut (the step then adds nothing)."""
        if len(self.line.rest_slack) == 0:
            return np.zeros(0)
        y = self.line.rest_load()
        band_chol_solve(self._chol, y)
        return y

    # -- state (views of ``self.state``, the arrays the compiled step works on) ---------------
    def _vector(name: str) -> property:  # type: ignore[misc]
        def get(self: ContactSimulation) -> np.ndarray:
            return getattr(self.state, name)

        def put(self: ContactSimulation, value: np.ndarray) -> None:
            getattr(self.state, name)[:] = value

        return property(get, put)

    def _number(index: int, counter: bool = False, kind: type = float) -> property:  # type: ignore[misc]
        def get(self: ContactSimulation):
            return kind((self.state.counters if counter else self.state.scalars)[index])

        def put(self: ContactSimulation, value: float) -> None:
            (self.state.counters if counter else self.state.scalars)[index] = value

        return property(get, put)

    d = _vector("d")
    v = _vector("v")
    a = _vector("a")
    p = _vector("p")
    vp = _vector("vp")
    ap = _vector("ap")
    roof_rest = _vector("roof_rest")
    x = _number(X)
    offset = _number(OFFSET)  # distance already shifted out of the window (endless)
    input_force = _number(INPUT_FORCE)
    steps = _number(STEPS, True, int)
    active_set_passes_max = _number(PASSES_MAX, True, int)
    #: steps whose active set did not settle (see step)
    active_set_unconverged = _number(UNCONVERGED, True, int)
    del _vector, _number

    # The controlled contact's penetration and contact flag (contact 0; the state keeps a copy of
    # both where the compiled loop reads them).
    @property
    def delta(self) -> float:
        return float(self.state.scalars[DELTA])

    @delta.setter
    def delta(self, value: float) -> None:
        self.state.deltas[0] = self.state.scalars[DELTA] = value

    @property
    def in_contact(self) -> bool:
        return bool(self.state.counters[IN_CONTACT])

    @in_contact.setter
    def in_contact(self, value: bool) -> None:
        self.state.touching[0] = self.state.counters[IN_CONTACT] = int(value)

    @property
    def contact_positions(self) -> np.ndarray:
        """Each contact point's distance from the line's start (plus what an endless line shifted)."""
        return np.array([pantograph_contact(self.constants, self.state, k)[1] for k in range(len(self.lags))])

    @property
    def contact_forces(self) -> np.ndarray:
        """Each contact's penalty force [N] (0 where it does not touch)."""
        return np.array([pantograph_contact(self.constants, self.state, k)[0] for k in range(len(self.lags))])

    @property
    def slack(self) -> np.ndarray:
        """The slack droppers, ascending."""
        return self.state.slack[: self.state.counters[N_SLACK]].copy()

    @slack.setter
    def slack(self, value: np.ndarray) -> None:
        value = np.asarray(value, dtype=np.int64)
        self.state.slack[: len(value)] = value
        self.state.counters[N_SLACK] = len(value)
        # A moving window takes its own droppers (and rows) at the next step: it chooses afresh.
        self.state.counters[WINDOW] = -1

    # -- initial states ------------------------------------------------------------------------
    def _place_pantographs(self, heads: np.ndarray, forces: np.ndarray) -> None:
        """Every pantograph at rest with its head at ``heads[k]`` pressed by ``forces[k]``."""
        p = np.empty(len(self.p))
        for k, panto in enumerate(self.pantographs):
            p[self.dof_start[k] : self.dof_start[k] + panto.n] = panto.static_positions(heads[k], forces[k])
        self.p = p
        self.vp[:] = self.ap[:] = 0.0
        self.roof_rest = self.p.copy()  # roof springs unloaded in the static state

    def start_touching(self) -> None:
        """Line at static equilibrium, pantographs at rest with the heads just touching (F = 0)."""
        self.d[:] = self.v[:] = self.a[:] = 0.0
        self.slack = self.line.rest_slack
        xs = self.x - self.lags
        self._place_pantographs(np.array([self.line.static_height(x) for x in xs]), np.zeros(len(xs)))
        self.input_force = 0.0
        self.state.touching[:] = 0
        self.state.deltas[:] = 0.0
        self.in_contact = False
        self.delta = 0.0

    def _forces(self, force: float) -> np.ndarray:
        """The uplift of each contact: ``force`` on the controlled one, each passive one's own."""
        forces = self.uplifts.copy()
        forces[0] = force
        return forces

    def _static(self, forces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(line deviation, head heights) of the static equilibrium under ``forces`` at the contact
        points, droppers taut (the linear static solve)."""
        f = np.zeros(self.line.n_dof)
        points = [self.line.contact_interpolation(x) for x in self.x - self.lags]
        for (dofs, n), fk in zip(points, forces, strict=True):
            f[dofs] += fk * n
        d = self.line.solve_static(f)
        heads = [
            self.line.static_height(x) + float(n @ d[dofs]) + fk / self.kp
            for x, (dofs, n), fk in zip(self.x - self.lags, points, forces, strict=True)
        ]
        return d, np.array(heads)

    def relax_roof_springs(self, force: float) -> None:
        """Each pantograph's roof springs at rest in the static state under its own uplift alone
        (``force`` on the controlled one), the rest of the (resting) state unchanged: a pantograph's
        static uplift is its force on the wire at working height. Each alone: no pantograph's
        setting depends on where the others are."""
        forces = self._forces(force)
        heads = np.empty(len(forces))
        for k in range(len(forces)):
            alone = np.zeros(len(forces))
            alone[k] = forces[k]
            heads[k] = self._static(alone)[1][k]
        p = self.p.copy()
        self._place_pantographs(heads, forces)
        self.roof_rest, self.p = self.p.copy(), p

    def start_static(self, force: float) -> None:
        """Static equilibrium of line and pantographs under the uplifts at their contact points
        (``force`` on the controlled one, each passive one's own)."""
        forces = self._forces(force)
        self.d, heads = self._static(forces)
        self.v[:] = self.a[:] = 0.0
        e = self._e0 + self.d[self._dwm] - self.d[self._dwc]
        if np.any(e < 0):
            raise ValueError("static uplift slackens a dropper: start from rest instead")
        self._place_pantographs(heads, forces)
        self.input_force = force
        self.state.touching[:] = 0
        self.state.deltas[:] = 0.0
        self.state.touching[: len(forces)] = 1  # (each on the wire it was placed on: the first set)
        self.state.deltas[: len(forces)] = forces / self.kp
        self.in_contact = True
        self.delta = force / self.kp

    def set_line_state(self, d: np.ndarray, v: np.ndarray) -> None:
        """Line deviation and velocity; acceleration from the equations of motion (with the
        current contact force; droppers taut)."""
        self.d, self.v = np.array(d, dtype=float), np.array(v, dtype=float)
        self.d[self.line.fixed] = self.v[self.line.fixed] = 0.0
        f = np.empty_like(self.d)
        band_matvec2(self._m, -self.alpha * self.v, self._k, -self.d - self.beta * self.v, f)  # M a
        for x, force in zip(self.x - self.lags, self.contact_forces, strict=True):
            dofs, n = self.line.contact_interpolation(x)
            f[dofs] += force * n
        m = self._m.copy()
        m[0, self.line.fixed] = 1.0  # anchored DOFs carry no mass: keep M invertible there
        f[self.line.fixed] = 0.0
        self.a = f
        band_chol_solve(chol_factor(m), self.a)

    # -- observables ---------------------------------------------------------------------------
    @property
    def packed(self) -> tuple[np.ndarray, ...]:
        """The step's constants and state packed for the compiled step (packing.pack): (floats,
        integers, layout) of the constants, then of the state; the state's arrays are live."""
        return self._packed

    @property
    def bands(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(M, K, the Cholesky factor of the step's matrix), banded, as the compiled step reads them."""
        return self._m, self._k, self._chol

    @property
    def time(self) -> float:
        return self.steps * self.dt

    @property
    def position(self) -> float:
        """Distance of the reference point x from the line's start (plus what an endless line
        shifted): the contact point of a pantograph with no lag."""
        return self.x + self.offset

    @property
    def contact_force(self) -> float:
        return self.kp * self.delta if self.in_contact else 0.0

    def uplift(self, x: float | None = None) -> float:
        """Contact-wire uplift from its static position at x (default: the contact point) [m]."""
        return self.line.contact_height(self.d, self.x if x is None else x)

    def dropper_elongation(self) -> np.ndarray:
        return self._e0 + self.d[self._dwm] - self.d[self._dwc]

    def energy(self) -> float:
        """Kinetic + strain energy of the deviation from static (line, pantograph, penalty) [J]."""
        tmp = np.empty_like(self.d)
        band_matvec2(self._m, self.v, self._k, self._zero, tmp)
        e = 0.5 * float(self.v @ tmp)
        band_matvec2(self._m, self._zero, self._k, self.d, tmp)
        e += 0.5 * float(self.d @ tmp)
        dp = self.p - self.roof_rest
        e += 0.5 * float(self.vp @ (self._pm @ self.vp))
        e += 0.5 * float(self.p @ (self._pstiff @ self.p))
        e += 0.5 * float(dp @ (np.diag(self._pground) @ dp))
        for touching, delta in zip(self.state.touching, self.state.deltas, strict=True):
            if touching:
                e += 0.5 * self.kp * delta**2
        # A slack dropper stores nothing, where the linear K (about static) counts k e^2 / 2.
        for j in self.slack:
            ej = self._e0[j] + self.d[self._dwm[j]] - self.d[self._dwc[j]]
            e -= 0.5 * self._kdrop[j] * ej**2
        return e

    # -- stepping ------------------------------------------------------------------------------
    def step(self, input_force: float) -> None:
        """Advance one dt with ``input_force`` [N] on the pantograph's input DOF at the new time
        (``step.fe_step``, compiled)."""
        if self._advance(input_force, 1, self._no_flex, self._no_readings) != STEP_OK:
            raise ValueError(divergence.reason(OFF_LINE, self.x + self.speed * self.dt))

    def advance(self, input_force: float, steps: int, flexibility: np.ndarray, readings: np.ndarray) -> None:
        """``steps`` x ``step`` and ``step.contact_readings`` into ``readings``, in one compiled call
        (``flexibility``: ``Line.element_flexibility()``)."""
        if self._advance(input_force, steps, flexibility, readings) != STEP_OK:
            raise ValueError(divergence.reason(OFF_LINE, self.x + self.speed * self.dt))

    def _advance(self, input_force: float, steps: int, flexibility: np.ndarray, readings: np.ndarray) -> int:
        return fe_advance_packed(*self._packed, input_force, steps, flexibility, readings)

    def prepare_contact_columns(self, x_from: float, x_to: float) -> None:
        """Solve the contact columns (A^-1 e_i, 2 solves per node) of the stretch the contact points
        sweep while x runs over [x_from, x_to] now: a run over it then never pays them (``step``
        otherwise does at each node's first use)."""
        for e_from, e_to in self.line.node_ranges(max(x_from - float(self.lags.max()), 0.0), x_to):
            prepare_unit_patches(self.constants, self.state, e_from, e_to)

    def readings_at(self, flexibility: np.ndarray, x: float, readings: np.ndarray) -> None:
        """``step.readings_at`` window position x (a contact point: x - lag) into ``readings``."""
        readings_at(self.constants, self.state, flexibility, x, readings)

    def readings(self, flexibility: np.ndarray, readings: np.ndarray) -> None:
        """``step.contact_readings`` of the present state into ``readings``."""
        contact_readings(self.constants, self.state, flexibility, readings)
