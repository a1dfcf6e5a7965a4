"""A whole line drawn by a layout rule: span lengths within a range, system heights that change by at
most a set step from mast to mast (docs/catenary.md, "A whole line", for the sources and the
*judgement* in each number).

Span k's length is uniform in [``span_min``, ``span_max``]; the system height at each mast is the
one before plus a step uniform in [-``max_height_step``, ``max_height_step``], reflected into
[``height_min``, ``height_max``] (a reflected step keeps its size, so the rule holds at every mast).
Each span carries ``droppers`` droppers: the first and last ``end_dropper`` from the masts, the
rest evenly between, and a parabolic design pre-sag between the end droppers whose middle value is
``presag_per_length`` x the span length (the pre-sag of the benchmark-like span, 55 mm on 55 m, is
that parabola at 1 per mille).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .data import SpanData


@dataclass(frozen=True)
class LayoutRule:
    """The layout rule of a catenary file (``layout:``)."""

    length: float  # m, the line is at least this long (whole spans)
    span_min: float  # m
    span_max: float  # m
    height_min: float  # m, system height
    height_max: float  # m
    max_height_step: float  # m, largest change of the system height from one mast to the next
    droppers: int  # per span
    end_dropper: float  # m, first and last dropper from the masts
    presag_per_length: float  # mid-span design pre-sag / span length
    rule: str = "uniform_spans"
    #: Tension sections (``sections``): spans per section, drawn uniform in [min, max]; 0: one
    #: tension length over the whole line.
    section_spans_min: int = 0
    section_spans_max: int = 0
    #: The outgoing wire's lift at the supports of an overlap [m] (``CatenaryData.overlap_lift``).
    overlap_lift: tuple[float, ...] = ()

    @property
    def overlap_spans(self) -> int:
        return max(len(self.overlap_lift) - 1, 0)


def dropper_layout(length: float, rule: LayoutRule) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """(dropper positions, design pre-sag) of a span of ``length`` [m] under ``rule``."""
    t = np.linspace(0.0, 1.0, rule.droppers)
    positions = rule.end_dropper + t * (length - 2.0 * rule.end_dropper)
    presag = 4.0 * rule.presag_per_length * length * t * (1.0 - t)
    return tuple(float(v) for v in positions), tuple(float(v) for v in presag)


def reflect(h: float, low: float, high: float) -> float:
    """``h`` folded back into [low, high] (the step's size unchanged)."""
    while not low <= h <= high:
        h = 2.0 * low - h if h < low else 2.0 * high - h
    return h


def draw_spans(rule: LayoutRule, rng: np.random.Generator) -> tuple[SpanData, ...]:
    """The spans of one line drawn under ``rule`` (as many as make ``rule.length``)."""
    spans: list[SpanData] = []
    total = 0.0
    height = float(rng.uniform(rule.height_min, rule.height_max))
    while total < rule.length - 1e-9:
        length = float(rng.uniform(rule.span_min, rule.span_max))
        positions, presag = dropper_layout(length, rule)
        spans.append(SpanData(length, height, positions, presag))
        total += length
        height = reflect(
            height + float(rng.uniform(-rule.max_height_step, rule.max_height_step)),
            rule.height_min,
            rule.height_max,
        )
    return tuple(spans)


def draw_sections(n_spans: int, rule: LayoutRule, rng: np.random.Generator) -> list[tuple[int, int]]:
    """(first span, spans) of each tension section of a line of ``n_spans`` spans: lengths uniform in
    [``section_spans_min``, ``section_spans_max``], consecutive sections sharing the overlap's
    spans. Where a draw would leave a rest shorter than the minimum, what is left is halved, or
    is one section (longer than the maximum) where halves would be too short."""
    lo, hi, n_o = rule.section_spans_min, rule.section_spans_max, rule.overlap_spans
    out: list[tuple[int, int]] = []
    first = 0
    while n_spans - first > hi:
        rest = n_spans - first
        count = int(rng.integers(lo, hi + 1))
        if rest - count + n_o < lo:  # the rest would be too short
            if rest + n_o < 2 * lo:
                break
            count = (rest + n_o + 1) // 2
        out.append((first, count))
        first += count - n_o
    out.append((first, n_spans - first))
    return out
