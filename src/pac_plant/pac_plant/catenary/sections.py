"""A whole line of tension sections joined by overlaps: each section its own wires, the pantograph
handed from one contact wire to the next where two run side by side (docs/catenary.md, "Tension
sections and overlaps").

* **Sections.** Each tension section is a ``Line`` of its own spans: contact wire and messenger
  anchored at its two end supports, its own droppers, steady arms and static equilibrium (a
  dropper may hang slack at rest, as on any line). Two sections share no DOF: stacked one after
  the other, K and M are block diagonal, a band of the same width, so the step solves all of them
  at once and its factor and columns are those of each section.
* **Overlaps.** Consecutive sections share the n = len(overlap_lift) - 1 spans of an overlap, each
  with its own wire there (its own drawn deviation). At the overlap's supports O_0 .. O_n the
  outgoing wire's reference height is raised by ``overlap_lift[i]`` and the incoming wire's by
  ``overlap_lift[n - i]``, linear between supports: the line each wire's w is measured from
  (``lift``, per node). A straight reference line adds nothing to the tensioned beam's equation
  (its second and fourth derivatives vanish), so each section's matrices and static solve stand
  as they are; the lift enters where the pantograph meets the wire (height w + lift) and puts the
  steady arm's rest on the lifted line. Neglected: the bending moment EI w'' at the reference's
  kinks over the supports (a few N m on a wire of EI = 195 N m^2, where the registration holds it).
* **Contacts.** The pantograph touches every wire above it: one contact per wire, so two in an
  overlap (``step.fe_step``: the sections of even index are one wire set, the odd ones the other).
  The readings (height, slope, stiffness, uplift under the pantograph) are the *running* wire's:
  the lower of the wires at x at rest, the outgoing one where both are at the same height.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .banded import chol_factor
from .data import CatenaryData, NumericalOptions
from .layout import Layout
from .line import DOFS_PER_NODE, Banded, Dropper, Line, hermite_shape


def section_lift(x: np.ndarray, supports: np.ndarray, lifts: np.ndarray) -> np.ndarray:
    """The reference lift [m] at the positions ``x`` of a wire raised by ``lifts`` at ``supports``,
    linear between them, 0 outside."""
    return np.where((x >= supports[0]) & (x <= supports[-1]), np.interp(x, supports, lifts), 0.0)


class SectionedLine(Line):
    """A whole line of ``data.sections`` tension sections (``Line``'s interface: K, M, the static
    state, droppers and the contact geometry of the running wire at x).

    ``sections[s]`` = (first node, end node) of section s in the stacked numbering, ``section_x[s]``
    its extent along the line [m], ``lift`` the reference lift of every node [m]."""

    def __init__(self, data: CatenaryData, options: NumericalOptions | None = None) -> None:
        options = NumericalOptions() if options is None else options
        if data.stitched:
            raise ValueError("a line of tension sections has no stitch wires")
        if len(data.sections) < 2 or len(data.overlap_lift) < 2:
            raise ValueError("a line of tension sections needs two sections or more and an overlap")
        self.data, self.options = data, options
        masts = np.concatenate([[0.0], np.cumsum([s.length for s in data.spans])])
        n_o = len(data.overlap_lift) - 1
        lift_out = np.asarray(data.overlap_lift, dtype=float)
        parts: list[Line] = []
        xs, lifts, ranges, extents = [], [], [], []
        node0 = 0
        for s, (first, spans) in enumerate(data.sections):
            part_data = dataclasses.replace(
                data, spans=spans, n_spans=len(spans), sections=(), overlap_lift=(), whole_line=True
            )
            part = Line(part_data, options)
            x = masts[first] + part.x
            lift = np.zeros(len(x))
            if s > 0:  # the incoming wire of the overlap at its start
                lift += section_lift(x, masts[first : first + n_o + 1], lift_out[::-1])
            if s < len(data.sections) - 1:  # the outgoing wire of the overlap at its end
                last = first + len(spans)
                lift += section_lift(x, masts[last - n_o : last + 1], lift_out)
            parts.append(part)
            xs.append(x)
            lifts.append(lift)
            ranges.append((node0, node0 + part.n_nodes))
            extents.append((float(x[0]), float(x[-1])))
            node0 += part.n_nodes
        self.parts = parts
        self.x = np.concatenate(xs)
        self.lift = np.concatenate(lifts)
        self.sections = np.array(ranges, dtype=np.int64)
        self.section_x = np.array(extents)
        self.n_nodes = len(self.x)
        self.n_dof = DOFS_PER_NODE * self.n_nodes
        self.n_spans = len(data.spans)
        self.length = float(masts[-1])
        self.h = np.diff(self.x)  # (the element across two sections is never located)
        self.has_droppers = all(p.has_droppers for p in parts)
        self.stitched = False
        self.period_spans, self.period_length, self.n_periods = self.n_spans, self.length, 1
        self.nodes_per_period, self.nodes_per_span = self.n_nodes, 0
        self._supports = True
        node_off = [r[0] for r in ranges]
        drop_off = np.concatenate([[0], np.cumsum([len(p.droppers.node) for p in parts])])
        self.droppers_per_period = int(drop_off[-1])

        self.fixed = np.concatenate([p.fixed + DOFS_PER_NODE * node_off[i] for i, p in enumerate(parts)])
        self.support_nodes = np.concatenate([p.support_nodes + node_off[i] for i, p in enumerate(parts)])
        dr = [p.droppers for p in parts]
        self.droppers = Dropper(
            node=np.concatenate([d.node + node_off[i] for i, d in enumerate(dr)]),
            x=np.concatenate([xs[i][d.node] for i, d in enumerate(dr)]),
            target_sag=np.concatenate([d.target_sag for d in dr]),
            height=np.concatenate([d.height for d in dr]),
            upper=np.concatenate([d.upper for d in dr]),
            length0=np.concatenate([d.length0 for d in dr]),
            stiffness=np.concatenate([d.stiffness for d in dr]),
            elongation0=np.concatenate([d.elongation0 for d in dr]),
        )
        self.rest_slack = np.concatenate([p.rest_slack + drop_off[i] for i, p in enumerate(parts)]).astype(
            np.int64
        )
        self.w_static = np.concatenate([p.w_static for p in parts])
        self.f_static = np.concatenate([p.f_static for p in parts])
        self.K, self.M = Banded(self.n_dof), Banded(self.n_dof)
        self.K.ab[:] = np.concatenate([p.K.ab for p in parts], axis=1)  # block diagonal: no entry between
        self.M.ab[:] = np.concatenate([p.M.ab for p in parts], axis=1)
        self._k_chol = chol_factor(self.K.ab)
        self.layout = Layout(
            x=self.x,
            support_x=masts,
            support_nodes=self.support_nodes,
            dropper_node=self.droppers.node,
            dropper_upper=self.droppers.upper,
            dropper_sag=self.droppers.target_sag,
            dropper_height=self.droppers.height,
            stitches=[],
            nodes_per_period=self.n_nodes,
            droppers_per_period=self.droppers_per_period,
            period_spans=self.n_spans,
            period_length=self.length,
        )

    # -- which wire ----------------------------------------------------------------------------
    def sections_at(self, x: float) -> list[int]:
        """The sections whose wire runs over x (two in an overlap), ascending."""
        return [s for s, (a, b) in enumerate(self.section_x) if a <= x <= b]

    def lift_at(self, x: float, s: int | None = None) -> float:
        """The reference lift [m] of section s's wire at x (default: the running wire's)."""
        s = self.running_section(x) if s is None else s
        e, xi = self._locate_in(s, x)
        return float((1.0 - xi) * self.lift[e] + xi * self.lift[e + 1])

    def wire_height(self, x: float, s: int) -> float:
        """Static height of section s's wire at x [m], its lift included."""
        e, xi = self._locate_in(s, x)
        n = hermite_shape(xi, self.h[e])
        return float(n @ self.w_static[self.contact_dofs(e)]) + self.lift_at(x, s)

    def running_section(self, x: float) -> int:
        """The section whose wire the pantograph runs on at x: the lower one at rest, the earlier
        where both are at the same height."""
        if not (0.0 <= x <= self.length):
            raise ValueError(f"position {x!r} m is off the line [0, {self.length}] m")
        near = self.sections_at(x)
        return min(near, key=lambda s: (self.wire_height(x, s), s))

    def locate(self, x: float) -> tuple[int, float]:
        """Element index and xi of position x on the running wire (``running_section``)."""
        return self._locate_in(self.running_section(x), x)

    def static_height(self, x: float) -> float:
        """Static height of the running wire at x [m], its lift included."""
        return self.wire_height(x, self.running_section(x))

    def static_slope(self, x: float) -> float:
        e, _ = self.locate(x)
        return super().static_slope(x) + float((self.lift[e + 1] - self.lift[e]) / self.h[e])

    def node_ranges(self, x_from: float, x_to: float) -> list[tuple[int, int]]:
        """(first, last) node of each section's stretch that contact points on [x_from, x_to] use."""
        out = []
        for s, (a, b) in enumerate(self.section_x):
            if b < x_from or a > x_to:
                continue
            e_from, _ = self._locate_in(s, max(x_from, a))
            e_to, _ = self._locate_in(s, min(x_to, b))
            out.append((e_from, e_to + 1))
        return out

    def set_dropper_lengths(self, length0: np.ndarray) -> None:
        raise ValueError("a line of tension sections solves its dropper lengths per section")
