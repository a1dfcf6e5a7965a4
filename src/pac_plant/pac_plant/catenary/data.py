"""A catenary as data: wires, spans (possibly unequal), droppers, supports, stitch wires.

Plain frozen dataclasses. ``CatenaryData()`` is the simple catenary of docs/catenary_data.md
§2 (benchmark-like, unconfirmed), which ``config/catenaries/benchmark_55m.yaml`` states as a
file; any other line comes from a catenary file (``catenary_file.load_catenary``, format in
docs/catenary.md). Only the numerical choices (element size, penalty, damping) are meant to
be varied on a stated data set.

A line is a *period* of spans (``spans``) repeated: the fixed section of the reference runs
has ``n_spans`` spans (the period cycled), the endless window of the plant whole periods.
"""

from __future__ import annotations

from dataclasses import dataclass

GRAVITY = 9.81  # m/s^2

#: The benchmark-like span of docs/catenary_data.md §2: droppers [m from the span's first
#: support] and the contact wire's design pre-sag there [m, positive down].
BENCHMARK_DROPPERS = (4.5, 10.25, 16.0, 21.75, 27.5, 33.25, 39.0, 44.75, 50.5)
BENCHMARK_PRESAG = (0.0, 0.024, 0.041, 0.052, 0.055, 0.052, 0.041, 0.024, 0.0)


@dataclass(frozen=True)
class WireData:
    """One tensioned wire: mass per length, tension, bending stiffness."""

    rho: float  # kg/m
    tension: float  # N
    ei: float  # N m^2

    @property
    def wave_speed(self) -> float:
        """c = sqrt(T / rho) [m/s] (docs/catenary_data.md §4)."""
        return (self.tension / self.rho) ** 0.5


@dataclass(frozen=True)
class StitchData:
    """A stitch wire at a support: a tensioned string clamped to the messenger ``length / 2``
    either side of the support, passing under it, carrying its own droppers to the contact wire."""

    length: float  # m
    tension: float  # N
    rho: float  # kg/m
    dropper_offsets: tuple[float, ...]  # m from the support (negative: in the span before it)
    presag: tuple[float, ...]  # design contact-wire pre-sag at those droppers [m, positive down]


@dataclass(frozen=True)
class SpanData:
    """One span: its length, the support where it starts (encumbrance, optional stitch wire)
    and its droppers."""

    length: float = 55.0  # m
    encumbrance: float = 1.2  # system height at the support where the span starts [m]
    dropper_positions: tuple[float, ...] = BENCHMARK_DROPPERS  # m from that support
    presag: tuple[float, ...] = BENCHMARK_PRESAG  # m, positive down
    stitch: StitchData | None = None  # at the support where the span starts


@dataclass(frozen=True)
class CatenaryData:
    """A catenary: ``spans`` is one period of the line (repeated); defaults: docs/catenary_data.md §2."""

    spans: tuple[SpanData, ...] = (SpanData(),)
    n_spans: int = 10  # spans of the fixed section (the reference runs): ``spans`` cycled
    contact: WireData = WireData(1.35, 22000.0, 195.0)
    messenger: WireData = WireData(1.08, 16000.0, 131.7)
    dropper_ea: float = 200e3  # N
    dropper_rho: float = 0.117  # kg/m
    clamp_mass_messenger: float = 0.195  # kg
    clamp_mass_contact: float = 0.165  # kg
    steady_arm_stiffness: float = 2673.58  # N/m
    messenger_support_stiffness: float = 500e3  # N/m
    steady_arm_mass: float = 0.0  # kg, moving with the contact wire at a support (weight: the cantilever's)
    messenger_support_mass: float = 0.0  # kg, moving with the messenger at a support
    gravity: float = GRAVITY
    name: str = "benchmark_55m"
    source: str = "docs/catenary_data.md §2"
    #: ``spans`` is one whole line (a layout rule drew it), not a period: the plant runs it as a
    #: fixed line from end to end, not as an endless window.
    whole_line: bool = False
    #: A whole line of several tension sections (``catenary/sections.py``): each section's first
    #: span in ``spans`` and its own spans (the wires it hangs: an overlap's spans are in two
    #: sections, each with its own deviation). Empty: one contact wire from end to end.
    sections: tuple[tuple[int, tuple[SpanData, ...]], ...] = ()
    #: The outgoing wire's lift above the contact-wire height at each support of an overlap [m]
    #: (the incoming wire's is the same, reversed); the overlap spans len(overlap_lift) - 1 spans.
    overlap_lift: tuple[float, ...] = ()

    @property
    def period(self) -> float:
        """Length of one period of the line (the spans of ``spans``) [m]."""
        return sum(s.length for s in self.spans)

    @property
    def span(self) -> float:
        """Mean span length [m]: the span where all spans are equal (what the lumped k(t) is told)."""
        return self.period / len(self.spans)

    @property
    def equal_spans(self) -> bool:
        return len({s.length for s in self.spans}) == 1

    @property
    def stitched(self) -> bool:
        return any(s.stitch is not None for s in self.spans)

    @property
    def dropper_positions(self) -> tuple[float, ...]:
        """The first span's droppers (all spans' where the line is uniform)."""
        return self.spans[0].dropper_positions

    @property
    def presag(self) -> tuple[float, ...]:
        return self.spans[0].presag

    @property
    def system_height(self) -> float:
        """The first support's encumbrance."""
        return self.spans[0].encumbrance


@dataclass(frozen=True)
class NumericalOptions:
    """Discretisation and damping choices (docs/catenary.md: convergence study, damping, penalty)."""

    element_size: float = 0.5  # m, upper bound: each dropper interval is split into equal elements
    #: Rayleigh damping C = alpha M + beta K of the line (the values the benchmark reproductions use).
    rayleigh_alpha: float = 0.0125  # 1/s
    rayleigh_beta: float = 1.0e-4  # s
    #: Penalty contact stiffness (the benchmark's 50 kN/m).
    contact_stiffness: float = 50e3  # N/m
