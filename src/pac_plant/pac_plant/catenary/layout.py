"""Where everything sits along a line of ``CatenaryData``: nodes, supports, droppers, stitch wires.

Pure geometry (no matrices): ``line.Line`` assembles on it. The spans of ``data.spans`` are one
period, cycled over the ``n_spans`` of the line; the mesh, the dropper numbering and every
index are periodic in that period, so an endless window can shift by whole periods.

Mesh: every support, dropper, stitch-wire clamp and stitch dropper is a node; each interval
between them is split into equal elements no longer than ``element_size``.

Node DOFs (``line.DOFS_PER_NODE`` = 4): (w_c, w'_c, w_m, w'_m) on a line without stitch wires
(both wires Hermite beams). A stitched line has a third wire in the same four slots: the
messenger becomes a string (linear elements on w_m; its EI is not used) and the fourth slot
holds the stitch wire's height w_s, so the band keeps its width (docs/catenary.md, "Stitch
wires"). A stitch wire's end elements join its first/last interior node to the messenger's
w_m at the clamp; slot 4 of every node outside a stitch wire is unused (fixed at 0).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .data import CatenaryData, SpanData

WC, RC, WM, RM = 0, 1, 2, 3  # DOF offsets within a node (line.py's)
WS = 3  # the stitch wire's height, in a stitched line (the messenger's slope slot)


def span_marks(data: CatenaryData, k: int) -> list[float]:
    """Positions in pattern span k that must be nodes [m from its first support], ascending."""
    spans = data.spans
    span, after = spans[k], spans[(k + 1) % len(spans)]
    marks = {0.0, span.length, *span.dropper_positions}
    if span.stitch is not None:  # the stitch wire of the support where the span starts
        marks.add(0.5 * span.stitch.length)
        marks.update(o for o in span.stitch.dropper_offsets if o > 0.0)
    if after.stitch is not None:  # ... and of the support where it ends
        marks.add(span.length - 0.5 * after.stitch.length)
        marks.update(span.length + o for o in after.stitch.dropper_offsets if o < 0.0)
    return sorted(marks)


def span_nodes(marks: list[float], element_size: float) -> np.ndarray:
    """Node positions within one span [0, L): the marks, intervals split evenly."""
    xs: list[float] = []
    for a, b in zip(marks[:-1], marks[1:], strict=True):
        n = max(1, math.ceil((b - a) / element_size - 1e-9))
        xs.extend(a + (b - a) * np.arange(n) / n)
    return np.array(xs)


def _height(a: SpanData, b: SpanData, x: float) -> float:
    """System height at x in span a (the next span b starts at its end): linear between supports."""
    if a.encumbrance == b.encumbrance:
        return a.encumbrance
    return a.encumbrance + (b.encumbrance - a.encumbrance) * x / a.length


@dataclass
class StitchWire:
    """One stitch wire on the mesh: its nodes (clamp to clamp) and the DOF of each (the messenger's
    w_m at a clamp, w_s in between; at an anchor support the line's end node, fixed)."""

    nodes: np.ndarray
    dofs: np.ndarray
    tension: float
    rho: float


@dataclass
class Layout:
    """Positions and indices of one line (``n_spans`` spans of ``data``'s period, cycled)."""

    x: np.ndarray  # node positions [m]
    support_x: np.ndarray  # every support, both ends included [m]
    support_nodes: np.ndarray  # the interior supports' nodes
    dropper_node: np.ndarray
    dropper_upper: np.ndarray  # DOF offset of the dropper's upper end: WM, or WS (stitch dropper)
    dropper_sag: np.ndarray  # design pre-sag [m, positive down]
    dropper_height: np.ndarray  # system height at the dropper [m]
    stitches: list[StitchWire]
    nodes_per_period: int
    droppers_per_period: int
    period_spans: int
    period_length: float


def build_layout(data: CatenaryData, element_size: float, n_spans: int, droppers: bool = True) -> Layout:
    """The layout of ``n_spans`` spans of ``data`` (each span k of the line is pattern span k mod p)."""
    spans, p = data.spans, len(data.spans)
    local = [span_nodes(span_marks(data, k), element_size) for k in range(p)]
    starts = [0.0]
    for s in range(n_spans):
        starts.append(starts[-1] + spans[s % p].length)
    if p == 1:  # s * L, not a running sum: the uniform line's nodes exactly as before
        starts = [s * spans[0].length for s in range(n_spans + 1)]
    x = np.concatenate([*(starts[s] + local[s % p] for s in range(n_spans)), [starts[-1]]])
    first_node = np.cumsum([0] + [len(local[s % p]) for s in range(n_spans)])
    last = len(x) - 1

    def node_at(pos: float) -> int:
        return int(np.argmin(np.abs(x - pos)))

    drops: list[tuple[float, int, int, float, float]] = []  # (x, node, upper, sag, height)
    if droppers:
        for s in range(n_spans):
            span, after = spans[s % p], spans[(s + 1) % p]
            for pos, sag in zip(span.dropper_positions, span.presag, strict=True):
                drops.append((starts[s] + pos, node_at(starts[s] + pos), WM, sag, _height(span, after, pos)))
    stitches: list[StitchWire] = []
    for i in range(n_spans + 1):  # every support, the two anchors included (half a stitch wire there)
        st = spans[i % p].stitch
        if st is None:
            continue
        xi = starts[i]
        a = node_at(xi - 0.5 * st.length) if i > 0 else 0
        b = node_at(xi + 0.5 * st.length) if i < n_spans else last
        nodes = np.arange(a, b + 1)
        dofs = 4 * nodes + WS
        if i > 0:
            dofs[0] = 4 * a + WM
        if i < n_spans:
            dofs[-1] = 4 * b + WM
        stitches.append(StitchWire(nodes, dofs, st.tension, st.rho))
        if not droppers:
            continue
        before, span, after = spans[(i - 1) % p], spans[i % p], spans[(i + 1) % p]
        for off, sag in zip(st.dropper_offsets, st.presag, strict=True):
            if (off < 0.0 and i == 0) or (off > 0.0 and i == n_spans):
                continue  # off the line
            h = _height(span, after, off) if off > 0.0 else _height(before, span, before.length + off)
            drops.append((xi + off, node_at(xi + off), WS, sag, h))
    drops.sort(key=lambda d: d[0])
    per_period = sum(
        len(sp.dropper_positions) + (len(sp.stitch.dropper_offsets) if sp.stitch else 0) for sp in spans
    )
    return Layout(
        x=x,
        support_x=np.array(starts),
        support_nodes=first_node[1:n_spans].astype(int),
        dropper_node=np.array([d[1] for d in drops], dtype=int),
        dropper_upper=np.array([d[2] for d in drops], dtype=int),
        dropper_sag=np.array([d[3] for d in drops]),
        dropper_height=np.array([d[4] for d in drops]),
        stitches=stitches,
        nodes_per_period=int(sum(len(v) for v in local)),
        droppers_per_period=per_period if droppers else 0,
        period_spans=p,
        period_length=data.period,
    )
