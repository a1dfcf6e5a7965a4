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
