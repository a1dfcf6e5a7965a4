"""Compiled (numba) kernels for symmetric banded matrices in LAPACK lower storage ab[k, j] = A[j+k, j].

The per-step work of the line is two banded mat-vecs and two banded Cholesky solves;
in numpy each is a dozen slicing operations (~10 us overhead each), compiled they
are one pass over the band.
"""

from __future__ import annotations

from typing import NamedTuple

import numba
import numpy as np


@numba.njit(cache=True)
def band_matvec2(a1: np.ndarray, x1: np.ndarray, a2: np.ndarray, x2: np.ndarray, out: np.ndarray) -> None:
    """out = A1 x1 + A2 x2 for symmetric banded A1, A2 (lower storage, same shape): one pass."""
    kd, n = a1.shape[0] - 1, a1.shape[1]
    for i in range(n):
        out[i] = a1[0, i] * x1[i] + a2[0, i] * x2[i]
    for j in range(n):
        y1, y2 = x1[j], x2[j]
        acc = 0.0
        top = min(kd, n - 1 - j)
        for k in range(1, top + 1):
            i = j + k
            p, q = a1[k, j], a2[k, j]
            out[i] += p * y1 + q * y2
            acc += p * x1[i] + q * x2[i]
        out[j] += acc


def chol_factor(ab: np.ndarray) -> np.ndarray:
    """The banded Cholesky factor of ``ab`` laid out for ``band_chol_solve``: (n, kd+1), row j
    holding L[j+k, j] for k = 0..kd with the diagonal inverted (cache-friendly, no division)."""
    from scipy.linalg import cholesky_banded

    cb = np.ascontiguousarray(cholesky_banded(ab, lower=True).T)
    cb[:, 0] = 1.0 / cb[:, 0]
    return cb


@numba.njit(cache=True)
def band_chol_solve(cb: np.ndarray, b: np.ndarray) -> None:
    """Solve L L^T x = b in place (b of shape (n,)); cb from ``chol_factor``."""
    n, kd = cb.shape[0], cb.shape[1] - 1
    for j in range(n):  # forward: L y = b, column-oriented
        bj = b[j] * cb[j, 0]
        b[j] = bj
        for k in range(1, min(kd, n - 1 - j) + 1):
            b[j + k] -= cb[j, k] * bj
    for j in range(n - 1, -1, -1):  # backward: L^T x = y, row-oriented
        acc = b[j]
        for k in range(1, min(kd, n - 1 - j) + 1):
            acc -= cb[j, k] * b[j + k]
        b[j] = acc * cb[j, 0]


@numba.njit(cache=True)
def newmark_rhs(
    m: np.ndarray,
    k: np.ndarray,
    d: np.ndarray,
    v: np.ndarray,
    a: np.ndarray,
    dt: float,
    alpha: float,
    beta: float,
    x1: np.ndarray,
    x2: np.ndarray,
    out: np.ndarray,
) -> None:
    """out = M (4/dt^2 d + 4/dt v + a) + C (2/dt d + v), C = alpha M + beta K (x1, x2: scratch)."""
    c0, c1, c2 = 4.0 / (dt * dt), 2.0 / dt, 4.0 / dt
    for i in range(d.shape[0]):
        w = c1 * d[i] + v[i]
        x1[i] = c0 * d[i] + c2 * v[i] + a[i] + alpha * w
        x2[i] = beta * w
    band_matvec2(m, x1, k, x2, out)


@numba.njit(cache=True)
def newmark_update(d: np.ndarray, v: np.ndarray, a: np.ndarray, d_new: np.ndarray, dt: float) -> None:
    """Average-acceleration update in place: a, v from the new displacement; d <- d_new."""
    c0, c2, h = 4.0 / (dt * dt), 4.0 / dt, 0.5 * dt
    for i in range(d.shape[0]):
        a_new = c0 * (d_new[i] - d[i]) - c2 * v[i] - a[i]
        v[i] += h * (a[i] + a_new)
        a[i] = a_new
        d[i] = d_new[i]


# -- the whole Newmark step of line + pantograph, compiled (``integrator.ContactSimulation``) ----------
MAX_ACTIVE_SET_PASSES = 25
UNIT_CACHE = 8  # A^-1 e_i kept for the DOFs of the last two contact elements

# Indices into StepState.scalars / StepState.counters.
X, OFFSET, DELTA, INPUT_FORCE = 0, 1, 2, 3
IN_CONTACT, STEPS, PASSES_MAX, UNCONVERGED, N_SLACK, UNIT_NEXT = 0, 1, 2, 3, 4, 5
#: ``fe_step`` return codes.
STEP_OK, STEP_OFF_LINE = 0, 1


class StepConstants(NamedTuple):
    """What does not change during a run: line matrices, factor, droppers, pantograph, numbers.

    ``ydrop_t[j]`` is A^-1 g_j for dropper j (contiguous row), ``ddrop`` = G^T A^-1 G.
    ``numbers`` = (dt, speed, alpha, beta, kp, c0, c1, length, span, shift_at);
    ``indices`` = (head, input, endless, shift_dofs, droppers_per_span).
    """

    m_ab: np.ndarray
    k_ab: np.ndarray
    chol: np.ndarray
    x_nodes: np.ndarray
    w_static: np.ndarray
    ydrop_t: np.ndarray
    ddrop: np.ndarray
    kdrop: np.ndarray
    e0: np.ndarray
    dwc: np.ndarray
    dwm: np.ndarray
    fixed: np.ndarray
    p_mass: np.ndarray
    p_damping: np.ndarray
    p_ainv: np.ndarray
    p_ground: np.ndarray
    numbers: np.ndarray
    indices: np.ndarray


class StepState(NamedTuple):
    """The integrator's whole state, mutated in place by ``fe_step``.

    ``scalars`` = (x, offset, delta, input_force); ``counters`` = (in_contact, steps,
    active_set_passes_max, active_set_unconverged, n_slack, next unit-cache slot);
    ``slack[:n_slack]`` the slack droppers (ascending); ``unit_keys``/``unit_cols`` the
    A^-1 e_i cache; ``work`` = 4 scratch vectors of the line's size.
    """

    d: np.ndarray
    v: np.ndarray
    a: np.ndarray
    p: np.ndarray
    vp: np.ndarray
    ap: np.ndarray
    roof_rest: np.ndarray
    scalars: np.ndarray
    counters: np.ndarray
    slack: np.ndarray
    unit_keys: np.ndarray
    unit_cols: np.ndarray
    work: np.ndarray


@numba.njit(cache=True)
def hermite_weights(x_nodes: np.ndarray, x: float) -> tuple[int, np.ndarray]:
    """(element, Hermite weights) of position x: ``Line.locate`` + ``hermite_shape`` (x on the line)."""
    e = np.searchsorted(x_nodes, x, side="right") - 1
    e = min(max(e, 0), x_nodes.shape[0] - 2)
    h = x_nodes[e + 1] - x_nodes[e]
    xi = (x - x_nodes[e]) / h
    x2, x3 = xi * xi, xi * xi * xi
    n = np.empty(4)
    n[0] = 1 - 3 * x2 + 2 * x3
    n[1] = h * (xi - 2 * x2 + x3)
    n[2] = 3 * x2 - 2 * x3
    n[3] = h * (x3 - x2)
    return e, n


@numba.njit(cache=True)
def _unit_solution(c: StepConstants, s: StepState, i: int) -> np.ndarray:
    """A^-1 e_i from the cache, solved (one banded solve) and cached FIFO when missing."""
    for slot in range(UNIT_CACHE):
        if s.unit_keys[slot] == i:
            return s.unit_cols[slot]
    slot = s.counters[UNIT_NEXT]
    s.counters[UNIT_NEXT] = (slot + 1) % UNIT_CACHE
    col = s.unit_cols[slot]
    col[:] = 0.0
    col[i] = 1.0
    band_chol_solve(c.chol, col)
    s.unit_keys[slot] = i
    return col


@numba.njit(cache=True)
def shift_window(c: StepConstants, s: StepState) -> None:
    """Move the window one span forward: states shift back one span, the new span is at rest."""
    sh, dps = c.indices[3], c.indices[4]
    for vec in (s.d, s.v, s.a):
        n = vec.shape[0]
        vec[: n - sh] = vec[sh:].copy()
        vec[n - sh :] = 0.0
        vec[c.fixed] = 0.0
    ns, kept = s.counters[N_SLACK], 0
    for q in range(ns):
        if s.slack[q] >= dps:
            s.slack[kept] = s.slack[q] - dps
            kept += 1
    s.counters[N_SLACK] = kept
    s.unit_keys[:] = -1
    s.scalars[X] -= c.numbers[8]
    s.scalars[OFFSET] += c.numbers[8]


@numba.njit(cache=True)
def _woodbury_coefficients(
    c: StepConstants,
    slack: np.ndarray,
    contact: bool,
    gc_y: float,
    gc_yc: float,
    gc_ydrop: np.ndarray,
    gd_y: np.ndarray,
    gd_yc: np.ndarray,
    ws_x: float,
) -> np.ndarray:
    """r - z of q = y + Y (r - z), z = cap^-1 U^T (y + Y r), cap = S^-1 + U^T A^-1 U."""
    kp = c.numbers[4]
    ns = slack.shape[0]
    m = ns + (1 if contact else 0)
    cap = np.zeros((m, m))
    uy = np.zeros(m)
    r = np.zeros(m)
    sinv = np.empty(m)
    for i in range(ns):
        si = slack[i]
        for j in range(ns):
            cap[i, j] = c.ddrop[si, slack[j]]
        cap[i, i] -= 1.0 / c.kdrop[si]
        uy[i] = gd_y[si]
        r[i] = c.kdrop[si] * c.e0[si]
        sinv[i] = -1.0 / c.kdrop[si]
    if contact:
        cap[ns, ns] = gc_yc + 1.0 / kp
        for j in range(ns):
            cap[ns, j] = gc_ydrop[slack[j]]
            cap[j, ns] = gd_yc[slack[j]]
        uy[ns] = gc_y
        r[ns] = kp * ws_x
        sinv[ns] = 1.0 / kp
    rhs = uy.copy()
    for i in range(m):
        acc = 0.0
        for j in range(m):
            cij = cap[i, j] - sinv[i] if i == j else cap[i, j]
            acc += cij * r[j]
        rhs[i] += acc
    return r - np.linalg.solve(cap, rhs)


@numba.njit(cache=True)
def fe_step(c: StepConstants, s: StepState, input_force: float) -> int:
    """One Newmark step of line + pantograph with ``input_force`` [N] at the new time (see
    ``integrator``): the window shift, right-hand side, banded solve, contact columns, active
    set with the Woodbury capacitance solve, update. Returns STEP_OK or STEP_OFF_LINE (the
    pantograph would leave the line; nothing but a due window shift has happened then)."""
    dt, speed, alpha, beta, kp, c0, c1 = (
        c.numbers[0],
        c.numbers[1],
        c.numbers[2],
        c.numbers[3],
        c.numbers[4],
        c.numbers[5],
        c.numbers[6],
    )
    length, shift_at = c.numbers[7], c.numbers[9]
    head, inp, endless = c.indices[0], c.indices[1], c.indices[2]
    x_new = s.scalars[X] + speed * dt
    if endless != 0 and x_new > shift_at:
        shift_window(c, s)
        x_new = s.scalars[X] + speed * dt
    if x_new > length:
        return STEP_OFF_LINE
    d, v, a = s.d, s.v, s.a
    y_l, x1, x2, yc_l = s.work[0], s.work[1], s.work[2], s.work[3]
    newmark_rhs(c.m_ab, c.k_ab, d, v, a, dt, alpha, beta, x1, x2, y_l)
    band_chol_solve(c.chol, y_l)
    e, nsh = hermite_weights(c.x_nodes, x_new)
    dofs = np.array([4 * e, 4 * e + 1, 4 * e + 4, 4 * e + 5])
    col = _unit_solution(c, s, dofs[0])
    for k in range(yc_l.shape[0]):
        yc_l[k] = -(col[k] * nsh[0])
    for i in range(1, 4):
        col = _unit_solution(c, s, dofs[i])
        for k in range(yc_l.shape[0]):
            yc_l[k] -= col[k] * nsh[i]
    # Pantograph.
    npn = s.p.shape[0]
    bp = np.empty(npn)
    u1 = c0 * s.p + (4.0 / dt) * s.vp + s.ap
    u2 = c1 * s.p + s.vp
    for i in range(npn):
        fi = c.p_ground[i] * s.roof_rest[i]
        if i == inp:
            fi += input_force
        acc1 = 0.0
        acc2 = 0.0
        for j in range(npn):
            acc1 += c.p_mass[i, j] * u1[j]
            acc2 += c.p_damping[i, j] * u2[j]
        bp[i] = fi + acc1 + acc2
    y_p = np.zeros(npn)
    for i in range(npn):
        for j in range(npn):
            y_p[i] += c.p_ainv[i, j] * bp[j]
    yc_p = c.p_ainv[:, head].copy()
    ws_x = 0.0
    gc_y = y_p[head]
    gc_yc = yc_p[head]
    for i in range(4):
        ws_x += nsh[i] * c.w_static[dofs[i]]
        gc_y -= nsh[i] * y_l[dofs[i]]
        gc_yc -= nsh[i] * yc_l[dofs[i]]
    nd = c.e0.shape[0]
    gc_ydrop = np.empty(nd)
    gd_y = np.empty(nd)
    gd_yc = np.empty(nd)
    for j in range(nd):
        acc = 0.0
        for i in range(4):
            acc += nsh[i] * c.ydrop_t[j, dofs[i]]
        gc_ydrop[j] = -acc
        gd_y[j] = y_l[c.dwm[j]] - y_l[c.dwc[j]]
        gd_yc[j] = yc_l[c.dwm[j]] - yc_l[c.dwc[j]]
    contact = s.counters[IN_CONTACT] != 0
    slack = s.slack[: s.counters[N_SLACK]].copy()
    passes = 0
    coef = np.zeros(1)
    delta = 0.0
    e_drop = np.empty(nd)
    while passes < MAX_ACTIVE_SET_PASSES:
        passes += 1
        ns = slack.shape[0]
        m = ns + (1 if contact else 0)
        if ns == 0:  # the usual case, in scalars
            coef = np.zeros(m)
            if contact:
                r_c = kp * ws_x
                coef[0] = r_c - (gc_y + gc_yc * r_c) / (gc_yc + 1.0 / kp)
        else:
            coef = _woodbury_coefficients(c, slack, contact, gc_y, gc_yc, gc_ydrop, gd_y, gd_yc, ws_x)
        delta = gc_y - ws_x
        for j in range(nd):
            e_drop[j] = c.e0[j] + gd_y[j]
        if ns:
            acc = 0.0
            for q in range(ns):
                acc += gc_ydrop[slack[q]] * coef[q]
            delta += acc
            for j in range(nd):
                acc = 0.0
                for q in range(ns):
                    acc += c.ddrop[j, slack[q]] * coef[q]
                e_drop[j] += acc
        if contact:
            delta += gc_yc * coef[ns]
            for j in range(nd):
                e_drop[j] += gd_yc[j] * coef[ns]
        new_contact = delta > 0.0
        new_slack = np.flatnonzero(e_drop < 0.0)
        consistent = new_contact == contact and new_slack.shape[0] == ns and np.all(new_slack == slack)
        if consistent or passes == MAX_ACTIVE_SET_PASSES:
            if not consistent:  # keep the set the solution was computed for; count it
                s.counters[UNCONVERGED] += 1
            break
        contact, slack = new_contact, new_slack
    s.counters[PASSES_MAX] = max(s.counters[PASSES_MAX], passes)
    ns = slack.shape[0]
    d_new = y_l  # scratch, consumed by newmark_update below
    p_new = y_p.copy()
    for q in range(ns):
        cq = coef[q]
        yq = c.ydrop_t[slack[q]]
        for k in range(d_new.shape[0]):
            d_new[k] += yq[k] * cq
    if contact:
        cc = coef[ns]
        for k in range(d_new.shape[0]):
            d_new[k] += yc_l[k] * cc
        for i in range(npn):
            p_new[i] += yc_p[i] * cc
    newmark_update(d, v, a, d_new, dt)
    for i in range(npn):
        ap_new = c0 * (p_new[i] - s.p[i]) - (4.0 / dt) * s.vp[i] - s.ap[i]
        s.vp[i] = s.vp[i] + 0.5 * dt * (s.ap[i] + ap_new)
        s.ap[i] = ap_new
        s.p[i] = p_new[i]
    s.scalars[X] = x_new
    s.counters[IN_CONTACT] = 1 if contact else 0
    s.slack[:ns] = slack
    s.counters[N_SLACK] = ns
    s.scalars[DELTA] = delta if contact else min(delta, 0.0)
    s.scalars[INPUT_FORCE] = input_force
    s.counters[STEPS] += 1
    return STEP_OK
