"""The contact line: mesh, Hermite beam matrices, droppers, supports, static equilibrium.

Both wires are tensioned Euler-Bernoulli beams (cubic Hermite elements, DOFs w and
w' per node) with the string (geometric) stiffness of their tension T:

    rho w_tt + EI w_xxxx - T w_xx = -rho g + (dropper, support and contact forces)

Small-displacement theory about two straight reference lines: the contact wire's
w is measured from the contact-wire height at the supports, the messenger's from
the messenger support height (system height H above). Node ordering interleaves
the wires, node i -> DOFs (w_c, w'_c, w_m, w'_m) = 4i .. 4i+3, so every matrix is
symmetric banded with 7 sub-diagonals (LAPACK lower band storage ``ab[k, j] = A[j+k, j]``).

Droppers are springs EA/L0 between the two wires at the same x (tension only: the
dynamics drop a dropper whose elongation goes negative, see ``integrator``); their
clamp masses and half of their own mass are lumped on the wire nodes. Steady arms
(contact wire) and messenger supports are springs to ground at the interior
supports; both wires are anchored (w = 0) at the two end supports. The unstrained
dropper lengths L0 are solved so that the static contact wire meets the target
pre-sag at every dropper (``solve_dropper_lengths``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import line_cache
from .banded import band_chol_solve, band_chol_solve_columns, band_inverse_band, chol_factor
from .data import CatenaryData, NumericalOptions, WireData
from .layout import WS, build_layout, span_marks
from .layout import span_nodes as _span_nodes
from .static import tension_only_equilibrium

DOFS_PER_NODE = 4
BANDWIDTH = 7  # sub-diagonals: node i couples with node i+1 only
WC, RC, WM, RM = 0, 1, 2, 3  # DOF offsets within a node
#: Droppers whose pre-tension responses one pass of the chord's set-up solves side by side.
PRETENSION_BLOCK = 64


def hermite_shape(xi: float, h: float) -> np.ndarray:
    """Cubic Hermite shape functions at xi in [0, 1] for (w_a, w'_a, w_b, w'_b)."""
    x2, x3 = xi * xi, xi * xi * xi
    return np.array([1 - 3 * x2 + 2 * x3, h * (xi - 2 * x2 + x3), 3 * x2 - 2 * x3, h * (x3 - x2)])


def _matrices4(rows: list[list[np.ndarray]]) -> np.ndarray:
    """4 x 4 matrices from their entries (each of one shape S): an array of shape S + (4, 4)."""
    return np.stack([np.stack(row, axis=-1) for row in rows], axis=-2)


def beam_matrices(w: WireData, h: float | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Element (stiffness = bending + string, consistent mass) of a tensioned beam of length h;
    h an array of lengths: one pair per element (shape h.shape + (4, 4))."""
    h = np.asarray(h, dtype=float)
    one = np.ones_like(h)
    # h**3 element by element: numpy's array power may take a vector path that rounds otherwise
    # (on some CPUs), and the matrices are the same to the bit whether built one by one or at once.
    cube = np.array([x**3 for x in h.ravel()]).reshape(h.shape)
    kb = np.asarray(w.ei / cube)[..., None, None] * _matrices4(
        [
            [12 * one, 6 * h, -12 * one, 6 * h],
            [6 * h, 4 * h * h, -6 * h, 2 * h * h],
            [-12 * one, -6 * h, 12 * one, -6 * h],
            [6 * h, 2 * h * h, -6 * h, 4 * h * h],
        ]
    )
    kg = np.asarray(w.tension / (30 * h))[..., None, None] * _matrices4(
        [
            [36 * one, 3 * h, -36 * one, 3 * h],
            [3 * h, 4 * h * h, -3 * h, -h * h],
            [-36 * one, -3 * h, 36 * one, -3 * h],
            [3 * h, -h * h, -3 * h, 4 * h * h],
        ]
    )
    m = np.asarray(w.rho * h / 420)[..., None, None] * _matrices4(
        [
            [156 * one, 22 * h, 54 * one, -13 * h],
            [22 * h, 4 * h * h, 13 * h, -3 * h * h],
            [54 * one, 13 * h, 156 * one, -22 * h],
            [-13 * h, -3 * h * h, -22 * h, 4 * h * h],
        ]
    )
    return kb + kg, m


def gravity_load(w: WireData, h: float | np.ndarray, g: float) -> np.ndarray:
    """Consistent nodal load of the wire's own weight over one element (downwards); h an array of
    lengths: one load per element (shape h.shape + (4,))."""
    h = np.asarray(h, dtype=float)
    return np.asarray(-w.rho * g)[..., None] * np.stack([h / 2, h * h / 12, h / 2, -h * h / 12], axis=-1)


def string_matrices(w: WireData, h: float) -> tuple[np.ndarray, np.ndarray]:
    """Element (stiffness T/h, consistent mass) of a tensioned string of length h, DOFs (w_a, w_b)."""
    return w.tension / h * np.array([[1.0, -1.0], [-1.0, 1.0]]), w.rho * h / 6 * np.array(
        [[2.0, 1.0], [1.0, 2.0]]
    )


def span_nodes(data: CatenaryData, element_size: float) -> np.ndarray:
    """Node positions within the first span [0, L): every dropper is a node, intervals split evenly."""
    return _span_nodes(span_marks(data, 0), element_size)


class Banded:
    """Symmetric banded matrix in LAPACK lower storage, assembled in place."""

    def __init__(self, n: int, kd: int = BANDWIDTH) -> None:
        self.ab = np.zeros((kd + 1, n))
        self.n = n
        self.kd = kd

    def add(self, i: int, j: int, v: float) -> None:
        """A[i, j] += v and A[j, i] += v (once on the diagonal)."""
        if i < j:
            i, j = j, i
        self.ab[i - j, j] += v

    def add_block(self, dofs: list[int] | np.ndarray, block: np.ndarray) -> None:
        for a, i in enumerate(dofs):
            for b, j in enumerate(dofs):
                if i >= j:
                    self.ab[i - j, j] += block[a, b]

    def add_blocks(self, dofs: np.ndarray, blocks: np.ndarray) -> None:
        """``add_block(dofs[e], blocks[e])`` for e = 0, 1, ... in one go, each entry's sums in
        the same order (``np.add.at`` adds in index order)."""
        i, j = dofs[:, :, None], dofs[:, None, :]
        lower = np.broadcast_to(i >= j, blocks.shape)
        rows, cols = np.broadcast_to(i - j, blocks.shape)[lower], np.broadcast_to(j, blocks.shape)[lower]
        np.add.at(self.ab, (rows, cols), blocks[lower])

    def dense(self) -> np.ndarray:
        a = np.zeros((self.n, self.n))
        for k in range(self.kd + 1):
            idx = np.arange(self.n - k)
            a[idx + k, idx] = self.ab[k, : self.n - k]
            a[idx, idx + k] = self.ab[k, : self.n - k]
        return a


@dataclass
class Dropper:
    """Index arrays over all droppers of the line."""

    node: np.ndarray  # node index (contact and messenger ends share it)
    x: np.ndarray  # position along the line [m]
    target_sag: np.ndarray  # m (positive down)
    height: np.ndarray  # system height at the dropper [m]: its unstrained length with zero pre-sag
    upper: np.ndarray  # DOF offset of its upper end: WM (messenger) or WS (a stitch wire)
    length0: np.ndarray  # unstrained length [m]
    stiffness: np.ndarray  # EA / L0 [N/m]
    elongation0: np.ndarray  # static elongation [m] (> 0: in tension; < 0: hanging slack at rest)

    @property
    def wc(self) -> np.ndarray:
        return DOFS_PER_NODE * self.node + WC

    @property
    def wm(self) -> np.ndarray:
        return DOFS_PER_NODE * self.node + self.upper

    @property
    def static_tension(self) -> np.ndarray:
        """Force at rest [N]: a dropper carries tension only (a slack one, none)."""
        return self.stiffness * np.maximum(self.elongation0, 0.0)


class Line:
    """A catenary section of ``n_spans`` spans, assembled and in static equilibrium.

    ``w_static`` is the static displacement of every DOF (gravity; droppers carry tension only,
    ``rest_slack`` the ones that hang slack at rest, usually none); the dynamics use the deviation
    d = w - w_static, so ``M``, ``K`` (line only, every dropper taut) act on d.
    """

    def __init__(
        self,
        data: CatenaryData | None = None,
        options: NumericalOptions | None = None,
        n_spans: int | None = None,
        droppers: bool = True,
        supports: bool = True,
    ) -> None:
        data = CatenaryData() if data is None else data
        options = NumericalOptions() if options is None else options
        self.data = data
        self.options = options
        self.n_spans = data.n_spans if n_spans is None else n_spans
        layout = build_layout(data, options.element_size, self.n_spans, droppers)
        self.layout = layout
        self.x = layout.x
        self.n_nodes = len(self.x)
        self.n_dof = DOFS_PER_NODE * self.n_nodes
        self.length = float(layout.support_x[-1])
        self.h = np.diff(self.x)
        self.has_droppers = droppers
        # Periodicity (an endless window shifts by whole periods of ``data.spans``).
        self.period_spans = layout.period_spans
        self.period_length = layout.period_length
        self.nodes_per_period = layout.nodes_per_period
        self.droppers_per_period = layout.droppers_per_period
        self.n_periods = self.n_spans // self.period_spans
        self.nodes_per_span = self.nodes_per_period if self.period_spans == 1 else 0  # 0: spans differ
        # Constrained DOFs: both wires anchored at the two end supports; a stitched line's stitch
        # slot wherever no stitch wire runs.
        last = self.n_nodes - 1
        fixed = [WC, WM, DOFS_PER_NODE * last + WC, DOFS_PER_NODE * last + WM]
        self.stitched = data.stitched
        if self.stitched:
            free = np.zeros(self.n_nodes, dtype=bool)
            for st in layout.stitches:
                free[st.nodes[1:-1]] = True
            free[[0, last]] = False
            fixed += [DOFS_PER_NODE * int(i) + WS for i in np.flatnonzero(~free)]
        self.fixed = np.array(sorted(fixed))
        self.support_nodes = layout.support_nodes
        self._supports = supports
        nodes = layout.dropper_node
        nd = len(nodes)
        self.droppers = Dropper(
            node=nodes,
            x=self.x[nodes],
            target_sag=layout.dropper_sag,
            height=layout.dropper_height,
            upper=layout.dropper_upper,
            length0=layout.dropper_height.copy(),
            stiffness=data.dropper_ea / layout.dropper_height,
            elongation0=np.zeros(nd),
        )
        # One tension section: every node on one wire, nowhere lifted (``sections.SectionedLine``).
        self.sections = np.array([[0, self.n_nodes]], dtype=np.int64)
        self.section_x = np.array([[0.0, self.length]])
        self.lift = np.zeros(self.n_nodes)
        self._assemble_wires()
        self.solve_dropper_lengths()

    # -- assembly ------------------------------------------------------------------------------
    def _assemble_wires(self) -> None:
        d = self.data
        kw, mw = Banded(self.n_dof), Banded(self.n_dof)
        fw = np.zeros(self.n_dof)
        # A stitched line's messenger is a string: its slope slot carries the stitch wire (layout.py).
        beams = ((d.contact, WC),) if self.stitched else ((d.contact, WC), (d.messenger, WM))
        # Every element of a wire at once: the wires' entries are apart, so each entry's sum has
        # its terms in element order, as added one by one.
        first = 4 * np.arange(len(self.h))[:, None]
        for wire, off in beams:
            ke, me = beam_matrices(wire, self.h)
            dofs = first + np.array([off, off + 1, 4 + off, 4 + off + 1])
            kw.add_blocks(dofs, ke)
            mw.add_blocks(dofs, me)
            np.add.at(fw, dofs.ravel(), gravity_load(wire, self.h, d.gravity).ravel())
        if self.stitched:
            for e, h in enumerate(self.h):
                self._add_string(kw, mw, fw, d.messenger, [4 * e + WM, 4 * (e + 1) + WM], h)
        for st in self.layout.stitches:
            wire = WireData(st.rho, st.tension, 0.0)
            for i in range(len(st.nodes) - 1):
                h = self.x[st.nodes[i + 1]] - self.x[st.nodes[i]]
                self._add_string(kw, mw, fw, wire, [int(st.dofs[i]), int(st.dofs[i + 1])], h)
        if self._supports:
            for n in self.support_nodes:
                kw.add(4 * n + WC, 4 * n + WC, d.steady_arm_stiffness)
                kw.add(4 * n + WM, 4 * n + WM, d.messenger_support_stiffness)
                if d.steady_arm_mass:
                    mw.add(4 * n + WC, 4 * n + WC, d.steady_arm_mass)
                if d.messenger_support_mass:
                    mw.add(4 * n + WM, 4 * n + WM, d.messenger_support_mass)
        self._k_wires, self._m_wires, self._f_wires = kw.ab.copy(), mw.ab.copy(), fw

    def _add_string(
        self, kw: Banded, mw: Banded, fw: np.ndarray, wire: WireData, dofs: list[int], h: float
    ) -> None:
        """One string element (messenger of a stitched line, a stitch wire) with its weight."""
        ke, me = string_matrices(wire, h)
        kw.add_block(dofs, ke)
        mw.add_block(dofs, me)
        fw[dofs] -= 0.5 * wire.rho * self.data.gravity * h

    def _assemble(self) -> None:
        """K, M and the static load for the current dropper lengths (droppers taut)."""
        d, dr = self.data, self.droppers
        k, m = Banded(self.n_dof), Banded(self.n_dof)
        k.ab[:], m.ab[:] = self._k_wires, self._m_wires
        f = self._f_wires.copy()
        # Dropper: spring k_d between w_c and w_m; elongation e = H + w_m - w_c - L0.
        half = 0.5 * d.dropper_rho * dr.length0
        ic, im, kd = dr.wc, dr.wm, dr.stiffness
        pre = kd * (dr.height - dr.length0)
        mc, mm = d.clamp_mass_contact + half, d.clamp_mass_messenger + half
        # Every dropper at once, each entry's terms in the order of a loop over the droppers
        # (np.add.at adds in index order): k_d on both ends and -k_d between them, the
        # pre-tension and the lumped weights on the load, the lumped masses.
        upper, lower = np.maximum(ic, im), np.minimum(ic, im)
        rows = np.stack([np.zeros_like(ic), np.zeros_like(im), upper - lower], axis=1).ravel()
        cols = np.stack([ic, im, lower], axis=1).ravel()
        np.add.at(k.ab, (rows, cols), np.stack([kd, kd, -kd], axis=1).ravel())
        load = np.stack([pre, -pre, -(mc * d.gravity), -(mm * d.gravity)], axis=1).ravel()
        np.add.at(f, np.stack([ic, im, ic, im], axis=1).ravel(), load)
        np.add.at(
            m.ab,
            (np.zeros(2 * len(ic), dtype=np.int64), np.stack([ic, im], axis=1).ravel()),
            np.stack([mc, mm], axis=1).ravel(),
        )
        for i in self.fixed:
            k.ab[:, i] = 0.0
            m.ab[:, i] = 0.0
            for kk in range(1, BANDWIDTH + 1):
                if i - kk >= 0:
                    k.ab[kk, i - kk] = 0.0
                    m.ab[kk, i - kk] = 0.0
            k.ab[0, i] = 1.0
            f[i] = 0.0
        self.K, self.M, self.f_static = k, m, f
        self._k_chol = chol_factor(k.ab)

    def solve_static(self, f: np.ndarray) -> np.ndarray:
        """K^-1 f (droppers taut), f of shape (n_dof,) or (n_dof, m)."""
        f = np.array(f, dtype=float, order="C")
        f[self.fixed] = 0.0
        if f.ndim == 1:
            band_chol_solve(self._k_chol, f)
        else:
            band_chol_solve_columns(self._k_chol, f)
        return f

    def solve_dropper_lengths(self, tolerance: float = 1e-9, max_iterations: int = 50) -> None:
        """Unstrained dropper lengths that put the static contact wire at -presag at every dropper.

        The static solution is linear in the dropper pre-tension terms p_j = k_j (H - L0_j):
        w = K^-1 (f_g + B p), so p solves a small linear system W p = -presag - w_g with
        W = (K^-1 B) at the droppers' contact-wire DOFs; k_j = EA / L0_j depends on L0, hence
        passes until L0 moves less than ``tolerance`` [m]. A periodic line solves W afresh each
        pass (a few dozen droppers; its committed results were computed so); a whole line's ~500
        droppers would make that 500 solves a pass (48 s of its set-up), so it takes chord steps
        (:meth:`_chord_dropper_lengths`).
        """
        if self.data.whole_line:
            self._whole_line_dropper_lengths(tolerance, max_iterations)
            return
        d, dr = self.data, self.droppers
        nd = len(dr.node)
        for _ in range(max_iterations):
            self._assemble()
            if nd == 0:
                break
            # Load without the pre-tension terms, and one column per dropper for them.
            pre = dr.stiffness * (dr.height - dr.length0)
            f_g = self.f_static.copy()
            np.add.at(f_g, dr.wc, -pre)
            np.add.at(f_g, dr.wm, pre)
            b = np.zeros((self.n_dof, nd))
            b[dr.wc, np.arange(nd)] = 1.0
            b[dr.wm, np.arange(nd)] = -1.0
            w_g = self.solve_static(f_g)
            w_b = self.solve_static(b)
            p = np.linalg.solve(w_b[dr.wc, :], -dr.target_sag - w_g[dr.wc])
            length0 = d.dropper_ea * dr.height / (d.dropper_ea + p)
            change = float(np.max(np.abs(length0 - dr.length0)))
            dr.length0 = length0
            dr.stiffness = d.dropper_ea / dr.length0
            if change < tolerance:
                break
        self.set_dropper_lengths(dr.length0)

    def _whole_line_dropper_lengths(self, tolerance: float, max_iterations: int) -> None:
        """The chord passes, or their lengths as a run of the same line kept them (``line_cache``,
        where the environment names a cache): checked, then set as the passes would set them."""
        dr = self.droppers
        key = line_cache.line_key(
            self.data, self.options, self.n_spans, self.has_droppers, self._supports, tolerance
        )
        kept = line_cache.read(key, len(dr.node))
        if kept is not None:
            start = dr.length0.copy()
            self.set_dropper_lengths(kept)
            residual = self.presag_residual()
            if residual <= line_cache.RESIDUAL_BOUND:
                return
            line_cache.reject(key, f"its pre-sag is {residual:.1e} m off the target")
            dr.length0, dr.stiffness = start, self.data.dropper_ea / start
        self._chord_dropper_lengths(tolerance, max_iterations)
        line_cache.write(key, dr.length0)

    def presag_residual(self) -> float:
        """Largest |w_c + pre-sag| over the droppers [m] with every dropper taut: how far the
        present dropper lengths leave the static contact wire from its target (0 when solved)."""
        if not len(self.droppers.node):
            return 0.0
        w = self.solve_static(self.f_static)
        return float(np.max(np.abs(w[self.droppers.wc] + self.droppers.target_sag)))

    def _chord_dropper_lengths(self, tolerance: float, max_iterations: int) -> None:
        """:meth:`solve_dropper_lengths` by chord steps: each pass corrects p by the residual of
        the present K (r = -presag - w_c, one solve) through W of the first pass. The fixed point
        is the same (r = 0 there); a pass costs one solve instead of one per dropper.

        A dropper's stiffness k_j = EA / L0_j = (EA + p_j) / H_j grows with p_j, which takes back
        part of each step: dw/dp_j = K^-1 b_j s_j with s_j = (H_j + w_m - w_c) / H_j (the dropper's
        present length over its height; 0.5-1 on a drawn line, where p_j reaches 0.9 EA). Each step
        is divided by that s_j (a diagonal Newton correction of the chord, no solve): the residual
        then shrinks ~2x a pass instead of ~1.4x, and the passes reach ``tolerance`` (they did not
        within 50 passes without it: 5e-9 m at the 50th on realistic_3km)."""
        d, dr = self.data, self.droppers
        nd = len(dr.node)
        self._assemble()
        if nd == 0:
            self.set_dropper_lengths(dr.length0)
            return
        chord = np.linalg.inv(self._pretension_response(dr.wc, dr.wm))
        for _ in range(max_iterations):
            pre = dr.stiffness * (dr.height - dr.length0)
            w = self.solve_static(self.f_static)  # f_static holds the present pre-tensions
            taken_back = (dr.height + w[dr.wm] - w[dr.wc]) / dr.height
            p = pre + chord @ (-dr.target_sag - w[dr.wc]) / taken_back
            length0 = d.dropper_ea * dr.height / (d.dropper_ea + p)
            change = float(np.max(np.abs(length0 - dr.length0)))
            dr.length0 = length0
            dr.stiffness = d.dropper_ea / dr.length0
            self._assemble()
            if change < tolerance:
                break
        else:
            raise ValueError(
                f"{d.name or 'line'}: the dropper lengths did not converge in {max_iterations} passes "
                f"(last change {change:.1e} m, tolerance {tolerance:.0e} m)"
            )
        self.set_dropper_lengths(dr.length0)

    def _pretension_response(self, wc: np.ndarray, wm: np.ndarray) -> np.ndarray:
        """W[i, j] = (K^-1 b_j)[wc_i], b_j = e_wc_j - e_wm_j: the contact wire's static response at
        each dropper to each dropper's pre-tension pair (droppers taut). The columns are solved
        side by side, a block at a time (``banded.band_chol_solve_columns``: one pass over the
        factor for a block of columns, not one per column)."""
        nd = len(wc)
        response = np.empty((nd, nd))
        for first in range(0, nd, PRETENSION_BLOCK):
            block = np.arange(first, min(nd, first + PRETENSION_BLOCK))
            cols = np.zeros((self.n_dof, len(block)))
            cols[wc[block], np.arange(len(block))] = 1.0
            cols[wm[block], np.arange(len(block))] = -1.0
            cols[self.fixed] = 0.0
            band_chol_solve_columns(self._k_chol, cols, int(min(wc[block].min(), wm[block].min())))
            response[:, block] = cols[wc, :]
        return response

    def set_dropper_lengths(self, length0: np.ndarray) -> None:
        """Static equilibrium with the unstrained dropper lengths ``length0`` [m] (e.g. solved on
        another mesh: what the pre-sag then is, is measured, not imposed)."""
        d, dr = self.data, self.droppers
        dr.length0 = np.array(length0, dtype=float)
        dr.stiffness = d.dropper_ea / dr.length0
        self._assemble()
        w_taut = self.solve_static(self.f_static)
        e_taut = dr.height + w_taut[dr.wm] - w_taut[dr.wc] - dr.length0
        # A dropper that would have to push hangs slack instead (the taut state, untouched, where none does).
        rest = tension_only_equilibrium(self.solve_static, w_taut, e_taut, dr.wc, dr.wm, dr.stiffness)
        self.w_static, dr.elongation0, self.rest_slack = rest.w, rest.elongation, rest.slack

    def node_ranges(self, x_from: float, x_to: float) -> list[tuple[int, int]]:
        """(first, last) node of the stretch that contact points on [x_from, x_to] use."""
        return [(self.locate(x_from)[0], self.locate(x_to)[0] + 1)]

    def rest_load(self) -> np.ndarray:
        """The constant load that keeps the taut-dropper K in equilibrium at the tension-only rest
        state: minus the forces the slack droppers would carry as springs, -sum_j k_j e0_j g_j over
        ``rest_slack`` (zero where no dropper hangs slack). With it, d = 0 is at rest in the
        dynamics about ``w_static`` (docs/catenary.md, "Slack droppers at rest")."""
        dr, f = self.droppers, np.zeros(self.n_dof)
        j = self.rest_slack
        force = dr.stiffness[j] * dr.elongation0[j]
        np.add.at(f, dr.wm[j], -force)
        np.add.at(f, dr.wc[j], force)
        return f

    # -- geometry of a point on the contact wire ----------------------------------------------
    def locate(self, x: float) -> tuple[int, float]:
        """Element index and local coordinate xi in [0, 1] of position x on the line."""
        if not (0.0 <= x <= self.length):
            raise ValueError(f"position {x!r} m is off the line [0, {self.length}] m")
        return self._locate_in(0, x)

    def _locate_in(self, s: int, x: float) -> tuple[int, float]:
        """``locate`` on the nodes of tension section s (``sections``; a plain line has one)."""
        lo, hi = (int(v) for v in self.sections[s])
        e = lo + int(np.searchsorted(self.x[lo:hi], x, side="right")) - 1
        e = min(max(e, lo), hi - 2)
        return e, (x - self.x[e]) / self.h[e]

    def contact_dofs(self, e: int) -> np.ndarray:
        """The contact-wire DOFs of element e: (w_a, w'_a, w_b, w'_b)."""
        return np.array([4 * e + WC, 4 * e + RC, 4 * (e + 1) + WC, 4 * (e + 1) + RC])

    def contact_interpolation(self, x: float) -> tuple[np.ndarray, np.ndarray]:
        """(DOFs, Hermite weights) such that w_c(x) = weights . q[DOFs]."""
        e, xi = self.locate(x)
        return self.contact_dofs(e), hermite_shape(xi, self.h[e])

    def contact_height(self, q: np.ndarray, x: float) -> float:
        dofs, n = self.contact_interpolation(x)
        return float(n @ q[dofs])

    def static_height(self, x: float) -> float:
        """Static contact-wire height at x [m] (negative: below the support height)."""
        return self.contact_height(self.w_static, x)

    def static_slope(self, x: float) -> float:
        """d/dx of the static contact-wire height at x (Hermite shape-function derivatives)."""
        e, xi = self.locate(x)
        h = self.h[e]
        x2 = xi * xi
        dn = np.array([6 * (x2 - xi) / h, 1 - 4 * xi + 3 * x2, 6 * (xi - x2) / h, 3 * x2 - 2 * xi])
        return float(dn @ self.w_static[self.contact_dofs(e)])

    def static_stiffness(self, xs: np.ndarray) -> np.ndarray:
        """Static point stiffness of the contact wire 1 / (N^T K^-1 N) at each x [N/m] (droppers taut)."""
        out = np.empty(len(xs))
        for i, x in enumerate(xs):
            dofs, n = self.contact_interpolation(float(x))
            f = np.zeros(self.n_dof)
            f[dofs] = n
            out[i] = 1.0 / float(n @ self.solve_static(f)[dofs])
        return out

    def element_flexibility(self) -> np.ndarray:
        """Per element, the 4x4 block of K^-1 on its contact DOFs (static stiffness at any x): read
        off the band of K^-1 (``banded.band_inverse_band``; an element's DOFs are 5 apart at most,
        inside the band of 7), a fixed DOF's rows and columns 0 (as ``solve_static`` gives)."""
        z = band_inverse_band(self._k_chol)
        z[:, self.fixed] = 0.0
        for i in self.fixed:  # the entries of a fixed DOF's row, stored in earlier columns
            for k in range(1, min(BANDWIDTH, i) + 1):
                z[k, i - k] = 0.0
        ne = self.n_nodes - 1
        dofs = 4 * np.arange(ne)[:, None] + np.array([WC, RC, 4 + WC, 4 + RC])  # contact_dofs(e)
        p, q = dofs[:, :, None], dofs[:, None, :]
        return z[np.abs(p - q), np.minimum(p, q)]  # (K^-1)[p, q] from the lower band
