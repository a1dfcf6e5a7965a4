"""A moving window on a whole line: the step works on the spans around the pantographs only.

A whole drawn line (3 km, ~25 000 DOFs) costs the step five times the endless ten-span window per
tick, although what the pantograph meets is decided within a few spans of it. The window keeps
the whole line's mesh, matrices and factor-free data (static state, dropper columns, contact
columns) and restricts each step to the DOF rows ``[lo, hi)`` of the spans around the contacts:
outside them the line is held at its static equilibrium (deviation, velocity and acceleration
zero), as the endless window holds its ends. Within the window the step is the whole line's step
with that state: the right-hand side, the banded solve and the update run over the window's rows
plus ``PAD`` rows on either side, where the solve sees the line beyond at rest (A^-1 decays by
about ten times per node, ``banded.CHUNK_OVERLAP``: what a solve truncated PAD rows further out
misses is rounding). So the window's one approximation is the state it discards: the waves that
leave it behind the pantographs, and the precursor that runs ahead of it, are set to rest.
A contact column (A^-1 e_i, solved once per node at its first use) is solved in the window where
the window holds it with a chunk's overlap to spare, else on the whole line (a stretch a plant
prepares ahead of the window).

Windows are fixed in advance, one per mean span: window g covers the line from g mean spans for
``spans`` mean spans plus the largest lag (a second pantograph's distance), and is used while the
reference point x has between ``spans / 2`` and ``spans / 2 + 1`` mean spans behind its rearmost
contact, as the endless window shifts (``integrator.ContactSimulation``). Each window has its own
factor (``banded.chunk_factor`` of its rows, a few ms each at set-up) and padded mass band; the
windows of a line all have the same number of rows (the largest: a window over an overlap holds
both sections' nodes), so the step's arrays have one shape.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .banded import CHUNK_OVERLAP, chunk_factor, narrow_band, pad_band
from .line import DOFS_PER_NODE, Line
from .step import UNIT_REACH

#: Rows solved on either side of the window (the line beyond at rest): twice a chunk's overlap, so
#: that the droppers within UNIT_REACH nodes outside the window, whose columns reach into it, read
#: a solution that is the whole line's to rounding.
PAD = 2 * CHUNK_OVERLAP


class WindowArrays(NamedTuple):
    """The windows of a line, as the step reads them (``step.StepConstants``, ``window_*``).

    ``x_leave[g]``: x at which window g gives way to g + 1 [m]; ``rows[g]`` = (first, end) of the
    rows solved, then (first, end) of the rows kept (the window proper); ``drops[g]`` = (first,
    end) of the droppers taken into the step (those whose columns reach the window); ``mass[g]``
    the padded mass band of the solved rows (``banded.pad_band``); ``factors`` the windows'
    ``chunk_factor`` stacked along the first axis (window g: rows g * F .. (g + 1) * F), ``starts``
    and ``bounds`` theirs."""

    x_leave: np.ndarray
    rows: np.ndarray
    drops: np.ndarray
    mass: np.ndarray
    factors: np.ndarray
    starts: np.ndarray
    bounds: np.ndarray


def no_windows(n_chunks: int, kd: int) -> WindowArrays:
    """The empty set: the step runs on the whole line."""
    return WindowArrays(
        np.zeros(0),
        np.zeros((0, 4), dtype=np.int64),
        np.zeros((0, 2), dtype=np.int64),
        np.zeros((0, kd + 1, kd)),
        np.zeros((0, kd + 1, n_chunks)),
        np.zeros((0, n_chunks), dtype=np.int64),
        np.zeros((0, n_chunks + 1), dtype=np.int64),
    )


def line_windows(
    line: Line, a_band: np.ndarray, m_band: np.ndarray, spans: float, lag: float
) -> WindowArrays:
    """The windows of ``spans`` mean spans (plus ``lag`` [m], the rearmost contact's distance behind
    x) along ``line``, with the step's matrix ``a_band`` and mass ``m_band`` (LAPACK lower band)."""
    if not spans >= 2.0:
        raise ValueError(f"a moving window needs at least 2 spans, got {spans}")
    support_x = np.asarray(line.layout.support_x, dtype=float)
    mean_span = float(np.mean(np.diff(support_x)))
    start_x, end_x = float(line.x[0]), float(line.x[-1])
    extent = spans * mean_span + lag
    n = line.n_dof
    starts_x: list[float] = []
    s = start_x
    while True:
        starts_x.append(s)
        if s + extent >= end_x:
            break
        s += mean_span
    kept = []
    for s in starts_x:  # every section's nodes over the window's stretch (an overlap: both wires)
        ranges = line.node_ranges(s, min(s + extent, end_x))
        low, high = min(first for first, _ in ranges), max(last for _, last in ranges)
        kept.append((DOFS_PER_NODE * low, DOFS_PER_NODE * (high + 1)))
    width = min(n, max(hi - lo for lo, hi in kept) + 2 * PAD)
    g_count = len(starts_x)
    rows = np.zeros((g_count, 4), dtype=np.int64)
    drops = np.zeros((g_count, 2), dtype=np.int64)
    node = np.asarray(line.droppers.node, dtype=np.int64)
    if np.any(np.diff(node) < 0):
        raise ValueError("a moving window needs the droppers numbered along the line")
    m_narrow, a_narrow = narrow_band(m_band), narrow_band(a_band)
    kd = m_narrow.shape[0] - 1
    mass = np.zeros((g_count, kd + 1, width + kd))
    factor_parts, start_parts, bound_parts = [], [], []
    for g, (lo, hi) in enumerate(kept):
        first = max(0, min(lo - PAD, n - width))
        rows[g] = (first, first + width, lo, hi)
        reach_lo, reach_hi = lo // DOFS_PER_NODE - UNIT_REACH, (hi - 1) // DOFS_PER_NODE + UNIT_REACH
        inside = np.flatnonzero((node >= reach_lo) & (node <= reach_hi))
        drops[g] = (inside[0], inside[-1] + 1) if inside.size else (0, 0)
        m_part, a_part = m_narrow[:, first : first + width].copy(), a_narrow[:, first : first + width].copy()
        for k in range(1, kd + 1):  # couplings that leave the solved rows (the line beyond at rest)
            m_part[k, width - k :] = 0.0
            a_part[k, width - k :] = 0.0
        mass[g] = pad_band(m_part)
        factors, chunk_starts, bounds = chunk_factor(a_part)
        factor_parts.append(factors)
        start_parts.append(chunk_starts)
        bound_parts.append(bounds)
    x_leave = np.array([s + lag + (spans / 2.0 + 1.0) * mean_span for s in starts_x])
    x_leave[-1] = np.inf
    return WindowArrays(
        x_leave,
        rows,
        drops,
        mass,
        np.ascontiguousarray(np.concatenate(factor_parts, axis=0)),
        np.ascontiguousarray(np.stack(start_parts)),
        np.ascontiguousarray(np.stack(bound_parts)),
    )
