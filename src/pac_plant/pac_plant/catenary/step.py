"""The whole Newmark step of line and pantograph, compiled: the contact by active set with a
Woodbury correction, the moving window, the slack droppers, and the plant's contact readings
(``integrator.ContactSimulation`` builds its constants and state; docs/numerics.md, "FE line").
"""

from __future__ import annotations

from typing import NamedTuple

import numba
import numpy as np

from .banded import CHUNK_OVERLAP, KD, chunk_solve
from .newmark import newmark_rhs_mass, newmark_update

# -- the whole Newmark step of line + pantograph, compiled (``integrator.ContactSimulation``) ----------
MAX_ACTIVE_SET_PASSES = 25
#: Nodes on each side of node i kept of A^-1 e_i (w and w' of the contact wire): beyond them the
#: column is < 1e-19 of its peak (``CHUNK_OVERLAP``).
UNIT_REACH = 20

# Indices into StepState.scalars / StepState.counters.
X, OFFSET, DELTA, INPUT_FORCE = 0, 1, 2, 3
IN_CONTACT, STEPS, PASSES_MAX, UNCONVERGED, N_SLACK, YC_LO, YC_HI, WINDOW = 0, 1, 2, 3, 4, 5, 6, 7
#: ``fe_step`` return codes.
STEP_OK, STEP_OFF_LINE = 0, 1


class StepConstants(NamedTuple):
    """What does not change during a run: line matrices, factor, droppers, pantograph, numbers.

    ``m_pad`` = ``pad_band(M)`` (the step needs no K, see ``newmark_rhs_mass``);
    ``ydrop_patches[j]`` is A^-1 g_j for dropper j on the rows ``unit_start`` of the dropper's
    node + 0..width-1 (outside, the column is < 1e-18 of its peak and taken as 0: its rows at the
    contact DOFs and the update for a slack dropper read the patch), ``ddrop`` = G^T A^-1 G.
    ``numbers`` = (dt, speed, alpha, beta, kp, c0, c1, length, span, shift_at);
    ``indices`` = (head, input, endless, shift_dofs, droppers_per_span, controlled contact) (head
    and input: the controlled pantograph's, in the stacked pantograph vector).
    Contact k (one per pantograph, the pantographs' DOFs stacked with the controlled one's first):
    ``p_heads[k]`` / ``p_inputs[k]`` its head and input DOF, ``p_lag[k]`` its distance behind x
    [m], ``p_uplift[k]`` the force held on its input (ignored for the controlled one) [N].
    ``y_rest`` = A^-1 ``Line.rest_load()`` where droppers hang slack at rest, else empty.
    Tension sections (``sections.SectionedLine``; one on any other line): ``sections[q]`` the
    node range of section q, ``section_x[q]`` its extent along the line [m], ``lift`` every node's
    reference lift [m]. ``indices[6]`` = the pantographs P; on a line of several sections contact
    P + k is pantograph k's on the other wire set (``p_wire``: 0 touches sections 0, 2, ...; 1
    the odd ones), with no input of its own (``p_inputs`` -1).
    A moving window on a whole line (``window.WindowArrays``; none: every ``window_*`` empty, the
    step runs on the whole line): ``window_x`` where each window gives way to the next [m],
    ``window_rows`` its rows solved and kept, ``window_drops`` its droppers, ``window_mass``,
    ``window_factors``, ``window_starts``, ``window_bounds`` its mass band and factor.
    """

    m_pad: np.ndarray
    chol: np.ndarray
    chunk_factors: np.ndarray
    chunk_starts: np.ndarray
    chunk_bounds: np.ndarray
    x_nodes: np.ndarray
    w_static: np.ndarray
    ydrop_patches: np.ndarray
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
    p_heads: np.ndarray
    p_inputs: np.ndarray
    p_lag: np.ndarray
    p_uplift: np.ndarray
    y_rest: np.ndarray
    sections: np.ndarray
    section_x: np.ndarray
    lift: np.ndarray
    p_wire: np.ndarray
    window_x: np.ndarray
    window_rows: np.ndarray
    window_drops: np.ndarray
    window_mass: np.ndarray
    window_factors: np.ndarray
    window_starts: np.ndarray
    window_bounds: np.ndarray


class StepState(NamedTuple):
    """The integrator's whole state, mutated in place by ``fe_step``.

    ``scalars`` = (x, offset, delta, input_force); ``counters`` = (in_contact, steps,
    active_set_passes_max, active_set_unconverged, n_slack, the range of ``work[1]`` that is
    not zero, the moving window in use: -1 none yet); ``slack[:n_slack]`` the slack droppers
    (ascending); ``unit_patches[i, r]`` = A^-1 e_(4i+r) on the rows ``unit_start(i)`` +
    0..width-1 (``unit_ready[i]``: computed);
    ``work`` (1 + contacts, n): scratch and A^-1 g_k of contact k in row 1 + k, not zero on
    ``yc_range[k]`` only; ``padded`` (2, n + 2 KD), ``chunk_work``: scratch. ``deltas[k]``,
    ``touching[k]``: penetration and contact of contact k (the controlled one's also in
    scalars[DELTA], counters[IN_CONTACT]). ``base_force[k]``: the force a moving roof passes to
    passive contact k's input over the step, added to its held uplift (0: a fixed roof; the
    controlled one's comes with ``input_force``).
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
    unit_patches: np.ndarray
    unit_ready: np.ndarray
    work: np.ndarray
    padded: np.ndarray
    chunk_work: np.ndarray
    deltas: np.ndarray
    touching: np.ndarray
    yc_range: np.ndarray
    base_force: np.ndarray


#: Where a contact has no wire over it (one wire set outside an overlap): its wire is put this far
#: above the head [m], so it never touches.
NO_WIRE = 1.0e3


@numba.njit(cache=True)
def hermite_weights(x_nodes: np.ndarray, x: float) -> tuple[int, np.ndarray]:
    """(element, Hermite weights) of position x: ``Line.locate`` + ``hermite_shape`` (x on the line)."""
    return hermite_in(x_nodes, 0, x_nodes.shape[0], x)


@numba.njit(cache=True)
def hermite_in(x_nodes: np.ndarray, lo: int, hi: int, x: float) -> tuple[int, np.ndarray]:
    """``hermite_weights`` on the nodes lo .. hi - 1 (one tension section)."""
    e = lo + int(np.searchsorted(x_nodes[lo:hi], x, side="right")) - 1
    e = min(max(e, lo), hi - 2)
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
def contact_section(c: StepConstants, x: float, wire: int) -> int:
    """The section of wire set ``wire`` (sections wire, wire + 2, ...) over x; -1 if none."""
    for q in range(wire, c.sections.shape[0], 2):
        if c.section_x[q, 0] <= x <= c.section_x[q, 1]:
            return q
    return -1


@numba.njit(cache=True)
def node_lift(c: StepConstants, e: int, x: float) -> float:
    """The reference lift [m] at x in element e (linear between its nodes)."""
    xi = (x - c.x_nodes[e]) / (c.x_nodes[e + 1] - c.x_nodes[e])
    return (1.0 - xi) * c.lift[e] + xi * c.lift[e + 1]


@numba.njit(cache=True)
def running_section(c: StepConstants, x: float) -> int:
    """``SectionedLine.running_section``: the lower wire over x at rest, the earlier where level."""
    if c.sections.shape[0] == 1:
        return 0
    best, best_height = 0, np.inf
    for q in range(c.sections.shape[0]):
        if c.section_x[q, 0] <= x <= c.section_x[q, 1]:
            e, n = hermite_in(c.x_nodes, c.sections[q, 0], c.sections[q, 1], x)
            hq = node_lift(c, e, x)
            for i in range(4):
                hq += n[i] * c.w_static[4 * e + (i % 2) + 4 * (i // 2)]
            if hq < best_height:
                best, best_height = q, hq
    return best


@numba.njit(cache=True)
def unit_start(n_dof: int, width: int, node: int) -> int:
    """First row of the stored part of A^-1 e_i for the DOFs of ``node`` (UNIT_REACH nodes back)."""
    return min(max(4 * (node - UNIT_REACH), 0), n_dof - width)


@numba.njit(cache=True)
def _unit_patches(c: StepConstants, s: StepState, node: int) -> None:
    """A^-1 e_i for w, w' of the contact wire at ``node`` (two banded solves, once per node)."""
    if s.unit_ready[node]:
        return
    n, width = s.d.shape[0], s.unit_patches.shape[2]
    lo = unit_start(n, width, node)
    col = s.work[0]
    g = s.counters[WINDOW]
    if g >= 0:  # the window's solve, where it holds the column with a chunk's overlap to spare
        lo_s, hi_s = c.window_rows[g, 0], c.window_rows[g, 1]
        if (lo_s > 0 and lo - lo_s < CHUNK_OVERLAP) or (hi_s < n and hi_s - lo - width < CHUNK_OVERLAP):
            g = -1
    for r in range(2):
        # Only the rows of the patch are solved for (``chunk_solve``'s first, last and keep).
        i = 4 * node + r
        if g < 0:
            col[:] = 0.0
            col[i] = 1.0
            chunk_solve(
                c.chunk_factors, c.chunk_starts, c.chunk_bounds, col, s.chunk_work, col[:0], i, i + 1, lo
            )
        else:  # the window's rows (the column is the whole line's to rounding: window.PAD)
            lo_s = c.window_rows[g, 0]
            col[lo_s : c.window_rows[g, 1]] = 0.0
            col[i] = 1.0
            window_solve(c, s, g, col, col[:0], i - lo_s, i + 1 - lo_s, lo - lo_s)
        s.unit_patches[node, r, :] = col[lo : lo + width]
    s.unit_ready[node] = 1


@numba.njit(cache=True)
def window_solve(
    c: StepConstants,
    s: StepState,
    g: int,
    b: np.ndarray,
    addend: np.ndarray,
    first: int = 0,
    last: int = -1,
    keep: int = 0,
) -> None:
    """``chunk_solve`` in place on the rows window g solves (the line beyond them at rest);
    ``addend``: those rows' addend, or empty; ``first``, ``last``, ``keep``: ``chunk_solve``'s,
    counted from the window's first row."""
    lo, hi = c.window_rows[g, 0], c.window_rows[g, 1]
    rows = c.window_factors.shape[0] // c.window_x.shape[0]
    factors = c.window_factors[g * rows : (g + 1) * rows]
    chunk_solve(
        factors, c.window_starts[g], c.window_bounds[g], b[lo:hi], s.chunk_work, addend, first, last, keep
    )


@numba.njit(cache=True)
def follow_window(c: StepConstants, s: StepState, x: float) -> int:
    """The window for the reference point at x; on a change, the rows it no longer keeps are set
    to rest and the slack droppers it no longer takes are dropped (the first time: every row
    outside it)."""
    g = s.counters[WINDOW]
    new = max(g, 0)
    while new < c.window_x.shape[0] - 1 and x >= c.window_x[new]:
        new += 1
    if new == g:
        return g
    lo, hi = c.window_rows[new, 2], c.window_rows[new, 3]
    old_lo, old_hi = (0, s.d.shape[0]) if g < 0 else (c.window_rows[g, 2], c.window_rows[g, 3])
    for vec in (s.d, s.v, s.a):
        vec[old_lo : max(lo, old_lo)] = 0.0
        vec[min(hi, old_hi) : old_hi] = 0.0
    j0, j1 = c.window_drops[new, 0], c.window_drops[new, 1]
    ns, kept = s.counters[N_SLACK], 0
    for q in range(ns):
        if j0 <= s.slack[q] < j1:
            s.slack[kept] = s.slack[q]
            kept += 1
    s.counters[N_SLACK] = kept
    s.counters[WINDOW] = new
    return new


@numba.njit(cache=True)
def prepare_unit_patches(c: StepConstants, s: StepState, node_from: int, node_to: int) -> None:
    """The contact columns of nodes node_from .. node_to (inclusive) now, not at their first use."""
    for node in range(max(node_from, 0), min(node_to, s.unit_ready.shape[0] - 1) + 1):
        _unit_patches(c, s, node)


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
    s.scalars[X] -= c.numbers[8]
    s.scalars[OFFSET] += c.numbers[8]


@numba.njit(cache=True)
def _woodbury_coefficients(
    c: StepConstants,
    slack: np.ndarray,
    active: np.ndarray,
    gc_y: np.ndarray,
    gc_yc: np.ndarray,
    gc_ydrop: np.ndarray,
    gd_y: np.ndarray,
    gd_yc: np.ndarray,
    ws_x: np.ndarray,
) -> np.ndarray:
    """r - z of q = y + Y (r - z), z = cap^-1 U^T (y + Y r), cap = S^-1 + U^T A^-1 U: U = the slack
    droppers' g_j, then the contacts in ``active`` (contact k: its row k of the gc_ arrays)."""
    kp = c.numbers[4]
    ns = slack.shape[0]
    m = ns + active.shape[0]
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
    for a in range(active.shape[0]):
        k, ia = active[a], ns + a
        for b in range(active.shape[0]):
            cap[ia, ns + b] = gc_yc[k, active[b]]
        cap[ia, ia] += 1.0 / kp
        for j in range(ns):
            cap[ia, j] = gc_ydrop[k, slack[j]]
            cap[j, ia] = gd_yc[k, slack[j]]
        uy[ia] = gc_y[k]
        r[ia] = kp * ws_x[k]
        sinv[ia] = 1.0 / kp
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
    """One Newmark step of line + pantographs with ``input_force`` [N] at the new time (see
    ``integrator``): the window shift, right-hand side, banded solve, contact columns, active
    set with the Woodbury capacitance solve, update. Returns STEP_OK or STEP_OFF_LINE (the
    pantograph would leave the line; nothing but a due window shift has happened then).

    Contact k (``p_lag``, ``p_heads``, ``p_inputs``) touches the wire at x - p_lag[k]; the
    controlled one (``indices[5]``) takes ``input_force``, every other one its held ``p_uplift``.
    With one contact the arithmetic is the single-pantograph step's, operation for operation."""
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
    endless, ctrl = c.indices[2], c.indices[5]
    x_new = s.scalars[X] + speed * dt
    if endless != 0 and x_new > shift_at:
        shift_window(c, s)
        x_new = s.scalars[X] + speed * dt
    if x_new > length:
        return STEP_OFF_LINE
    d, v, a = s.d, s.v, s.a
    n = d.shape[0]
    npc = c.p_lag.shape[0]
    nd = c.e0.shape[0]
    # The rows solved (lo_s .. hi_s) and kept (lo_k .. hi_k), the droppers taken (j0 .. j1): the
    # whole line, or a moving window's (``window``; before the contact columns, which use it).
    windowed = c.window_x.shape[0] > 0
    g, lo_s, hi_s, lo_k, hi_k, j0, j1 = -1, 0, n, 0, n, 0, nd
    if windowed:
        g = follow_window(c, s, x_new)
        lo_s, hi_s, lo_k, hi_k = (
            c.window_rows[g, 0],
            c.window_rows[g, 1],
            c.window_rows[g, 2],
            c.window_rows[g, 3],
        )
        j0, j1 = c.window_drops[g, 0], c.window_drops[g, 1]
    elem = np.empty(npc, dtype=np.int64)
    nsh = np.empty((npc, 4))
    dofs = np.empty((npc, 4), dtype=np.int64)
    sectioned = c.sections.shape[0] > 1
    lifted = np.zeros(npc)
    for k in range(npc):
        xk = x_new - c.p_lag[k]
        q = contact_section(c, xk, c.p_wire[k])
        if q < 0:  # no wire of this set over the head: a stand-in element, its wire far above
            q = c.p_wire[k]
            xk = min(max(xk, c.section_x[q, 0]), c.section_x[q, 1])
            lifted[k] = NO_WIRE
        e, w = hermite_in(c.x_nodes, c.sections[q, 0], c.sections[q, 1], xk)
        if sectioned and lifted[k] == 0.0:
            lifted[k] = node_lift(c, e, xk)
        elem[k] = e
        nsh[k] = w
        dofs[k, 0], dofs[k, 1], dofs[k, 2], dofs[k, 3] = 4 * e, 4 * e + 1, 4 * e + 4, 4 * e + 5
        _unit_patches(c, s, e)  # (before the solve: they use y_l as scratch)
        _unit_patches(c, s, e + 1)
    y_l = s.work[0]
    if windowed:  # (the solved rows' z keeps zero ends: nothing else writes the padded rows)
        rows = hi_s - lo_s
        z, tail = s.padded[0][: rows + 2 * KD], s.padded[1][:rows]
        newmark_rhs_mass(
            c.window_mass[g],
            d[lo_s:hi_s],
            v[lo_s:hi_s],
            a[lo_s:hi_s],
            dt,
            alpha,
            beta,
            z,
            tail,
            y_l[lo_s:hi_s],
        )
        window_solve(c, s, g, y_l, tail)
    else:
        z, tail = s.padded[0], s.padded[1, :n]
        newmark_rhs_mass(c.m_pad, d, v, a, dt, alpha, beta, z, tail, y_l)
        chunk_solve(c.chunk_factors, c.chunk_starts, c.chunk_bounds, y_l, s.chunk_work, tail)
    if c.y_rest.shape[0]:  # A^-1 of the constant rest load (droppers slack at rest; else empty)
        for i in range(lo_s, hi_s):
            y_l[i] += c.y_rest[i]
    # Contact columns A^-1 g_k (line part) from the stored patches; zero outside their [lo, hi).
    width = s.unit_patches.shape[2]
    for k in range(npc):
        yc_l = s.work[1 + k]
        yc_l[s.yc_range[k, 0] : s.yc_range[k, 1]] = 0.0
        for i in range(4):
            node = elem[k] + i // 2
            lo = unit_start(n, width, node)
            col = s.unit_patches[node, i % 2]
            for q in range(width):
                yc_l[lo + q] -= col[q] * nsh[k, i]
        s.yc_range[k, 0] = unit_start(n, width, elem[k])
        s.yc_range[k, 1] = unit_start(n, width, elem[k] + 1) + width
    # Pantographs (stacked: one block of the matrices each).
    npn = s.p.shape[0]
    bp = np.empty(npn)
    u1 = c0 * s.p + (4.0 / dt) * s.vp + s.ap
    u2 = c1 * s.p + s.vp
    for i in range(npn):
        fi = c.p_ground[i] * s.roof_rest[i]
        for k in range(npc):
            if i == c.p_inputs[k]:
                fi += input_force if k == ctrl else c.p_uplift[k] + s.base_force[k]
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
    # Projections on the contact directions g_k and on the dropper directions g_j.
    ws_x = np.zeros(npc)
    gc_y = np.empty(npc)
    gc_yc = np.empty((npc, npc))
    gc_ydrop = np.empty((npc, nd))
    gd_yc = np.empty((npc, nd))
    for k in range(npc):
        hk = c.p_heads[k]
        gc_y[k] = y_p[hk]
        for j in range(npc):
            gc_yc[k, j] = c.p_ainv[hk, c.p_heads[j]]
        for i in range(4):
            ws_x[k] += nsh[k, i] * c.w_static[dofs[k, i]]
            gc_y[k] -= nsh[k, i] * y_l[dofs[k, i]]
            for j in range(npc):
                gc_yc[k, j] -= nsh[k, i] * s.work[1 + j, dofs[k, i]]
        if sectioned:
            ws_x[k] += lifted[k]
    gd_y = np.empty(nd)
    drop_width = c.ydrop_patches.shape[1]
    for j in range(j0, j1):
        drop_lo = unit_start(n, drop_width, c.dwc[j] // 4)
        for k in range(npc):
            acc = 0.0
            for i in range(4):
                row = dofs[k, i] - drop_lo
                if 0 <= row < drop_width:  # (outside the patch the column is < 1e-18 of its peak)
                    acc += nsh[k, i] * c.ydrop_patches[j, row]
            gc_ydrop[k, j] = -acc
            gd_yc[k, j] = s.work[1 + k, c.dwm[j]] - s.work[1 + k, c.dwc[j]]
        gd_y[j] = y_l[c.dwm[j]] - y_l[c.dwc[j]]
    touch = s.touching.copy()
    slack = s.slack[: s.counters[N_SLACK]].copy()
    passes = 0
    coef = np.zeros(1)
    delta = np.zeros(npc)
    e_drop = np.empty(nd)
    active = np.flatnonzero(touch)
    while passes < MAX_ACTIVE_SET_PASSES:
        passes += 1
        ns = slack.shape[0]
        active = np.flatnonzero(touch)
        m = ns + active.shape[0]
        if ns == 0 and active.shape[0] <= 1:  # the usual case of one pantograph, in scalars
            coef = np.zeros(m)
            if m:
                k = active[0]
                r_c = kp * ws_x[k]
                coef[0] = r_c - (gc_y[k] + gc_yc[k, k] * r_c) / (gc_yc[k, k] + 1.0 / kp)
        else:
            coef = _woodbury_coefficients(c, slack, active, gc_y, gc_yc, gc_ydrop, gd_y, gd_yc, ws_x)
        for k in range(npc):
            delta[k] = gc_y[k] - ws_x[k]
        for j in range(j0, j1):
            e_drop[j] = c.e0[j] + gd_y[j]
        if ns:
            for k in range(npc):
                acc = 0.0
                for q in range(ns):
                    acc += gc_ydrop[k, slack[q]] * coef[q]
                delta[k] += acc
            for j in range(j0, j1):
                acc = 0.0
                for q in range(ns):
                    acc += c.ddrop[j, slack[q]] * coef[q]
                e_drop[j] += acc
        for b in range(active.shape[0]):
            kb, cb = active[b], coef[ns + b]
            for k in range(npc):
                delta[k] += gc_yc[k, kb] * cb
            for j in range(j0, j1):
                e_drop[j] += gd_yc[kb, j] * cb
        new_slack = np.flatnonzero(e_drop[j0:j1] < 0.0)
        if j0:  # (in place: no second array a pass)
            new_slack += j0
        consistent = new_slack.shape[0] == ns and np.all(new_slack == slack)
        for k in range(npc):
            new_touch = 1 if delta[k] > 0.0 else 0
            consistent = consistent and new_touch == touch[k]
            touch[k] = new_touch
        if consistent or passes == MAX_ACTIVE_SET_PASSES:
            if not consistent:  # keep the set the solution was computed for; count it
                s.counters[UNCONVERGED] += 1
                for k in range(npc):
                    touch[k] = 0
                for b in range(active.shape[0]):
                    touch[active[b]] = 1
            break
        slack = new_slack
    s.counters[PASSES_MAX] = max(s.counters[PASSES_MAX], passes)
    ns = slack.shape[0]
    d_new = y_l  # scratch, consumed by newmark_update below
    p_new = y_p.copy()
    width = c.ydrop_patches.shape[1]
    for q in range(ns):
        cq = coef[q]
        yq = c.ydrop_patches[slack[q]]
        lo = unit_start(n, width, c.dwc[slack[q]] // 4)
        for r in range(width):
            d_new[lo + r] += yq[r] * cq
    for b in range(active.shape[0]):
        kb, cc = active[b], coef[ns + b]
        yc_l = s.work[1 + kb]
        for r in range(s.yc_range[kb, 0], s.yc_range[kb, 1]):
            d_new[r] += yc_l[r] * cc
        for i in range(npn):
            p_new[i] += c.p_ainv[i, c.p_heads[kb]] * cc
    if windowed:
        newmark_update(d[lo_k:hi_k], v[lo_k:hi_k], a[lo_k:hi_k], d_new[lo_k:hi_k], dt)
    else:
        newmark_update(d, v, a, d_new, dt)
    for i in range(npn):
        ap_new = c0 * (p_new[i] - s.p[i]) - (4.0 / dt) * s.vp[i] - s.ap[i]
        s.vp[i] = s.vp[i] + 0.5 * dt * (s.ap[i] + ap_new)
        s.ap[i] = ap_new
        s.p[i] = p_new[i]
    s.scalars[X] = x_new
    for k in range(npc):
        s.touching[k] = touch[k]
        s.deltas[k] = delta[k] if touch[k] else min(delta[k], 0.0)
    s.counters[IN_CONTACT] = s.touching[ctrl]  # the controlled contact's, where the loop reads them
    s.scalars[DELTA] = s.deltas[ctrl]
    twin = ctrl + c.indices[6]
    if twin < npc:  # its contact on the other wire: the pantograph's penetration is the sum
        if s.touching[twin]:
            s.scalars[DELTA] = s.deltas[twin] + (s.deltas[ctrl] if s.touching[ctrl] else 0.0)
            s.counters[IN_CONTACT] = 1
        elif not s.touching[ctrl]:
            s.scalars[DELTA] = max(s.deltas[ctrl], s.deltas[twin])
    s.slack[:ns] = slack
    s.counters[N_SLACK] = ns
    s.scalars[INPUT_FORCE] = input_force
    s.counters[STEPS] += 1
    return STEP_OK


# Indices into the ``contact_readings`` output.
CONTACT_UPLIFT, SUPPORT_UPLIFT, STATIC_STIFFNESS, STATIC_HEIGHT, STATIC_SLOPE = 0, 1, 2, 3, 4


@numba.njit(cache=True)
def contact_readings(c: StepConstants, s: StepState, flexibility: np.ndarray, out: np.ndarray) -> None:
    """``readings_at`` the controlled pantograph's contact point."""
    readings_at(c, s, flexibility, s.scalars[X] - c.p_lag[c.indices[5]], out)


@numba.njit(cache=True)
def pantograph_contact(c: StepConstants, s: StepState, k: int) -> tuple[float, float]:
    """Contact k (pantograph k's head): its penalty force kp delta_k where it touches, else 0 [N],
    and its contact point's distance from the line's start (x plus what an endless line shifted,
    minus its lag) [m]. The one home of both: the compiled loop and ``ContactSimulation`` call it.
    On a line of tension sections the force is the sum over the wires the head touches."""
    force = c.numbers[4] * s.deltas[k] if s.touching[k] != 0 else 0.0
    for j in range(k + c.indices[6], c.p_lag.shape[0], c.indices[6]):
        if s.touching[j] != 0:
            force += c.numbers[4] * s.deltas[j]
    return force, s.scalars[X] + s.scalars[OFFSET] - c.p_lag[k]


@numba.njit(cache=True)
def readings_at(c: StepConstants, s: StepState, flexibility: np.ndarray, x: float, out: np.ndarray) -> None:
    """What the plant reports at a contact point x (``Line``'s formulas, compiled): the wire's
    uplift there and at the nearest support [m], the static point stiffness 1 / (N^T F_e N)
    from the element's 4x4 flexibility block [N/m], the static wire height [m] and slope."""
    span = c.numbers[8]
    q = running_section(c, x)
    lo, hi = c.sections[q, 0], c.sections[q, 1]
    e, n = hermite_in(c.x_nodes, lo, hi, x)
    dofs = np.array([4 * e, 4 * e + 1, 4 * e + 4, 4 * e + 5])
    up, ws, nfn = 0.0, 0.0, 0.0
    for i in range(4):
        up += n[i] * s.d[dofs[i]]
        ws += n[i] * c.w_static[dofs[i]]
        acc = 0.0
        for j in range(4):
            acc += flexibility[e, i, j] * n[j]
        nfn += n[i] * acc
    h = c.x_nodes[e + 1] - c.x_nodes[e]
    xi = (x - c.x_nodes[e]) / h
    x2 = xi * xi
    dn = (6 * (x2 - xi) / h, 1 - 4 * xi + 3 * x2, 6 * (xi - x2) / h, 3 * x2 - 2 * xi)
    slope = 0.0
    for i in range(4):
        slope += dn[i] * c.w_static[dofs[i]]
    if c.sections.shape[0] > 1:  # the running wire's lift (a whole line: no span to round to)
        ws += node_lift(c, e, x)
        slope += (c.lift[e + 1] - c.lift[e]) / h
    es, ns = hermite_in(c.x_nodes, lo, hi, np.rint(x / span) * span)
    sup = 0.0
    for i in range(4):
        sup += ns[i] * s.d[4 * es + (i % 2) + 4 * (i // 2)]
    out[CONTACT_UPLIFT] = up
    out[SUPPORT_UPLIFT] = sup
    out[STATIC_STIFFNESS] = 1.0 / nfn
    out[STATIC_HEIGHT] = ws
    out[STATIC_SLOPE] = slope


@numba.njit(cache=True)
def fe_advance(
    c: StepConstants,
    s: StepState,
    input_force: float,
    steps: int,
    flexibility: np.ndarray,
    readings: np.ndarray,
) -> int:
    """``steps`` x ``fe_step`` with the force held, then ``contact_readings`` (skipped if
    ``readings`` is empty): one plant tick."""
    for _ in range(steps):
        status = fe_step(c, s, input_force)
        if status != STEP_OK:
            return status
    if readings.shape[0]:
        contact_readings(c, s, flexibility, readings)
    return STEP_OK
