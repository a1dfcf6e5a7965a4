"""The catenary file (YAML): reading and checking it into ``CatenaryData`` + ``NumericalOptions``.

Format, with one complete example: docs/catenary.md, "The catenary file". The shipped presets
are ``config/catenaries/<name>.yaml``; ``catenary:=NAME`` names one of them, anything with a
``/`` or a ``.yaml`` / ``.yml`` ending is a path.

Every value is checked before anything is built; a bad file raises :class:`CatenaryFileError`,
one line naming the file, the line and column, the key, the value and what is allowed (a
``ParameterError``: the nodes and tools print it and exit 2).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from pac_common.data_file import DataFileError, Map, Presets, Reader, Seq

from .data import GRAVITY, CatenaryData, NumericalOptions, SpanData, StitchData, WireData
from .deviation import DeviationModel, apply_deviation
from .layout_rule import LayoutRule, draw_sections, draw_spans

#: The shipped presets, in the repository (found from this file's location, installed or not).
PRESET_FOLDER = Path("config") / "catenaries"
DEFAULT = "benchmark_55m"


class CatenaryFileError(DataFileError):
    """A catenary file that cannot be used; the message is one line."""

    KIND = "catenary"


@dataclass(frozen=True)
class CatenaryFile:
    """What a catenary file states: the line and the numerical options that go with it."""

    path: Path
    data: CatenaryData  # the line drawn with the file's ``line_seed`` where it has a rule or a model
    numerics: NumericalOptions
    drawing: LineDrawing | None = None  # how to draw the line again with another seed

    def line(self, seed: int | None = None) -> CatenaryData:
        """The line; drawn with ``seed`` instead of the file's ``line_seed`` if given (a line
        without a layout rule or a deviation model has nothing to draw: the same line)."""
        if seed is None or self.drawing is None:
            return self.data
        return self.drawing.draw(seed)

    def design_supports(self, seed: int | None = None) -> np.ndarray | None:
        """The supports of a whole line as designed [m from its start, both ends]: the spans its
        layout rule draws for ``seed`` (the file's ``line_seed`` if None), without the deviation
        (what the infrastructure manager publishes). None for a period (no layout rule)."""
        if self.drawing is None or self.drawing.layout is None:
            return None
        lengths = (
            [span.length for span in self.line(seed).spans]
            if seed is None
            else [span.length for span in draw_spans(self.drawing.layout, np.random.default_rng([seed, 0]))]
        )
        return np.concatenate(([0.0], np.cumsum(lengths)))

    def design_overlaps(self, seed: int | None = None) -> np.ndarray:
        """Where the line's tension sections overlap as designed: (start, end) rows [m from its
        start], the supports that bound each overlap's spans on :meth:`design_supports` (where
        the infrastructure manager's section plan puts them). No rows without sections."""
        supports = self.design_supports(seed)
        layout = None if self.drawing is None else self.drawing.layout
        if supports is None or layout is None or not layout.section_spans_min:
            return np.zeros((0, 2))
        split = (
            self.data.sections
            if seed is None
            else draw_sections(len(supports) - 1, layout, np.random.default_rng([seed, 2]))
        )
        firsts = [first for first, _ in split]
        n_o = layout.overlap_spans
        return np.array([[supports[first], supports[first + n_o]] for first in firsts[1:]]).reshape(-1, 2)


@dataclass(frozen=True)
class LineDrawing:
    """What a file draws: the spans (a layout rule, else the file's period) and their deviation."""

    base: CatenaryData  # the file's line before drawing (its spans: the stated period)
    layout: LayoutRule | None
    deviation: DeviationModel | None
    deviation_spans: int  # spans the deviation is drawn over (the period of the drawn line)

    def draw(self, seed: int) -> CatenaryData:
        """The line of ``seed``: the layout's spans (one whole line: n_spans = all of them, not
        cycled), then the deviation drawn over them. Layout and deviation take separate streams of
        the seed, so the same seed gives the same layout with or without a deviation model."""
        data = self.base
        if self.layout is not None:
            spans = draw_spans(self.layout, np.random.default_rng([seed, 0]))
            data = dataclasses.replace(data, spans=spans, n_spans=len(spans), whole_line=True)
        if self.deviation is not None:
            n = len(data.spans) if self.layout is not None else self.deviation_spans
            data = apply_deviation(data, self.deviation, n, np.random.default_rng([seed, 1]))
            if self.layout is None:  # a deviated period, cycled over the section as before
                data = dataclasses.replace(data, n_spans=max(data.n_spans, n))
        if self.layout is not None and self.layout.section_spans_min:
            data = self._sections(data, spans, seed)
        return data

    def _sections(self, data: CatenaryData, design: tuple[SpanData, ...], seed: int) -> CatenaryData:
        """``data`` as tension sections (``sections.SectionedLine``): each section the drawn line's
        spans, but the incoming wire over an overlap has a deviation of its own (a further
        stream of the seed); the outgoing wire and every span outside overlaps are the line the
        same seed draws without sections."""
        assert self.layout is not None
        rule, n_o = self.layout, self.layout.overlap_spans
        split = draw_sections(len(data.spans), rule, np.random.default_rng([seed, 2]))
        sections = []
        for s, (first, count) in enumerate(split):
            own = data.spans[first : first + count]
            if s > 0 and self.deviation is not None:
                wire = dataclasses.replace(data, spans=design[first : first + n_o])
                fresh = apply_deviation(wire, self.deviation, n_o, np.random.default_rng([seed, 3, s]))
                own = fresh.spans + own[n_o:]
            sections.append((first, tuple(own)))
        return dataclasses.replace(data, sections=tuple(sections), overlap_lift=rule.overlap_lift)


TOP_KEYS = (
    "name",
    "source",
    "section_spans",
    "gravity",
    "contact_wire",
    "messenger_wire",
    "droppers",
    "supports",
    "spans",
    "damping",
    "contact_stiffness",
    "layout",
    "deviation",
    "line_seed",
)
WIRE_KEYS = ("rho", "tension", "ei")
DROPPER_KEYS = ("ea", "rho", "clamp_mass_contact", "clamp_mass_messenger")
SUPPORT_KEYS = (
    "steady_arm_stiffness",
    "steady_arm_mass",
    "messenger_support_stiffness",
    "messenger_support_mass",
)
SPAN_KEYS = ("length", "encumbrance", "droppers", "presag", "stitch")
STITCH_KEYS = ("length", "tension", "rho", "droppers", "presag")
DAMPING_KEYS = ("rayleigh_alpha", "rayleigh_beta")
LAYOUT_KEYS = (
    "rule",
    "length",
    "span_min",
    "span_max",
    "height_min",
    "height_max",
    "max_height_step",
    "droppers",
    "end_dropper",
    "presag_per_length",
    "sections",
)
SECTION_KEYS = ("spans_min", "spans_max", "overlap_lift")
DEVIATION_KEYS = ("model", "vertical_sigma", "correlation_length", "longitudinal_sigma", "spans")
LAYOUT_RULES = ("uniform_spans",)
DEVIATION_MODELS = ("exponential_psd",)


def parse_catenary(text: str, source: str) -> tuple[CatenaryData, NumericalOptions]:
    """``CatenaryData`` and ``NumericalOptions`` of a catenary file's text (``source`` names it);
    a line with a layout rule or a deviation model drawn with the file's ``line_seed``."""
    data, options, _ = _parse(text, source)
    return data, options


def _parse(text: str, source: str) -> tuple[CatenaryData, NumericalOptions, LineDrawing | None]:
    r = Reader(source, CatenaryFileError)
    raw = r.parse(text, TOP_KEYS)
    for key in ("name", "source"):
        r.text(raw, key)
    wires = []
    for name in ("contact_wire", "messenger_wire"):
        w = r.mapping(raw, name, "", WIRE_KEYS)
        p = f"{name}."
        wires.append(
            WireData(
                rho=r.number(w, "rho", p, "kg/m", 0.0, 100.0),
                tension=r.number(w, "tension", p, "N", 0.0, 1e6),
                ei=r.number(w, "ei", p, "N m^2", 0.0, 1e5, low_open=False),
            )
        )
    dr = r.mapping(raw, "droppers", "", DROPPER_KEYS)
    sp = r.mapping(raw, "supports", "", SUPPORT_KEYS)
    layout = _layout(r, raw) if "layout" in raw else None
    spans_raw = raw.get("spans")
    if layout is not None:
        if "spans" in raw:
            raise r.fail("spans", spans_raw, "absent: the layout rule draws the spans", raw.marks["spans"])
        spans: tuple[SpanData, ...] = (SpanData(),)  # replaced by the drawn ones
    else:
        if not isinstance(spans_raw, Seq) or not spans_raw or not all(isinstance(s, Map) for s in spans_raw):
            raise r.fail(
                "spans", spans_raw, "a non-empty list of spans (mappings)", raw.marks.get("spans", raw.start)
            )
        spans = tuple(_span(r, s, i) for i, s in enumerate(spans_raw))
        _check_stitches(r, spans_raw, spans)
    section = raw.get("section_spans", 10)
    if isinstance(section, bool) or not isinstance(section, int) or not 2 <= section <= 1000:
        raise r.fail("section_spans", section, "an integer in [2, 1000]", raw.marks.get("section_spans"))
    damping = r.mapping(raw, "damping", "", DAMPING_KEYS)
    data = CatenaryData(
        spans=spans,
        n_spans=section,
        contact=wires[0],
        messenger=wires[1],
        dropper_ea=r.number(dr, "ea", "droppers.", "N", 0.0, 1e9),
        dropper_rho=r.number(dr, "rho", "droppers.", "kg/m", 0.0, 10.0, low_open=False),
        clamp_mass_contact=r.number(dr, "clamp_mass_contact", "droppers.", "kg", 0.0, 10.0, low_open=False),
        clamp_mass_messenger=r.number(
            dr, "clamp_mass_messenger", "droppers.", "kg", 0.0, 10.0, low_open=False
        ),
        steady_arm_stiffness=r.number(sp, "steady_arm_stiffness", "supports.", "N/m", 0.0, 1e9),
        messenger_support_stiffness=r.number(sp, "messenger_support_stiffness", "supports.", "N/m", 0.0, 1e9),
        steady_arm_mass=r.number(
            sp, "steady_arm_mass", "supports.", "kg", 0.0, 100.0, low_open=False, default=0.0
        ),
        messenger_support_mass=r.number(
            sp, "messenger_support_mass", "supports.", "kg", 0.0, 100.0, low_open=False, default=0.0
        ),
        gravity=r.number(raw, "gravity", "", "m/s^2", 9.7, 9.9, low_open=False, default=GRAVITY),
        name=raw["name"].strip(),
        source=" ".join(raw["source"].split()),
    )
    options = NumericalOptions(
        rayleigh_alpha=r.number(damping, "rayleigh_alpha", "damping.", "1/s", 0.0, 10.0, low_open=False),
        rayleigh_beta=r.number(damping, "rayleigh_beta", "damping.", "s", 0.0, 0.01, low_open=False),
        contact_stiffness=r.number(raw, "contact_stiffness", "", "N/m", 1e3, 1e7),
    )
    deviation, deviation_spans = _deviation(r, raw, data) if "deviation" in raw else (None, 0)
    seed = raw.get("line_seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed < 2**32:
        raise r.fail("line_seed", seed, "an integer in [0, 2^32)", raw.marks.get("line_seed"))
    if layout is None and deviation is None:
        if "line_seed" in raw:
            raise r.fail(
                "line_seed",
                seed,
                "absent: nothing is drawn (no layout, no deviation)",
                raw.marks["line_seed"],
            )
        return data, options, None
    drawing = LineDrawing(data, layout, deviation, deviation_spans)
    try:
        drawn = drawing.draw(seed)
    except ValueError as exc:  # a deviation that cannot keep the droppers in order
        raise r.fail("deviation.longitudinal_sigma", None, str(exc), raw.marks["deviation"]) from None
    return drawn, options, drawing


def _choice(r: Reader, m: Map, name: str, path: str, allowed: tuple[str, ...]) -> str:
    value = m.get(name)
    if value not in allowed:
        raise r.fail(f"{path}{name}", value, f"one of {', '.join(allowed)}", m.marks.get(name, m.start))
    return str(value)


def _count(r: Reader, m: Map, name: str, path: str, low: int, high: int, default: int | None = None) -> int:
    value = m.get(name, default)
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        raise r.fail(f"{path}{name}", value, f"an integer in [{low}, {high}]", m.marks.get(name, m.start))
    return value


def _layout(r: Reader, raw: Map) -> LayoutRule:
    m, p = r.mapping(raw, "layout", "", LAYOUT_KEYS), "layout."
    span_min = r.number(m, "span_min", p, "m", 20.0, 100.0)
    height_min = r.number(m, "height_min", p, "m", 0.2, 5.0)
    rule = LayoutRule(
        rule=_choice(r, m, "rule", p, LAYOUT_RULES),
        length=r.number(m, "length", p, "m", 100.0, 20000.0),
        span_min=span_min,
        span_max=r.number(m, "span_max", p, "m", span_min, 100.0, low_open=False),
        height_min=height_min,
        height_max=r.number(m, "height_max", p, "m", height_min, 5.0, low_open=False),
        max_height_step=r.number(m, "max_height_step", p, "m", 0.0, 1.0, low_open=False),
        droppers=_count(r, m, "droppers", p, 2, 30),
        end_dropper=r.number(m, "end_dropper", p, "m", 0.0, 0.25 * span_min),
        presag_per_length=r.number(m, "presag_per_length", p, "", 0.0, 0.005, low_open=False),
    )
    if m.get("sections") is not None:
        sm, q = r.mapping(m, "sections", p, SECTION_KEYS), f"{p}sections."
        lift = r.numbers(sm, "overlap_lift", q, "m", 0.0, 2.0, low_open=False, count=None)
        if not 2 <= len(lift) <= 4 or lift[0] != 0.0 or lift[-1] <= 0.0:
            raise r.fail(
                f"{q}overlap_lift",
                list(lift),
                "2 to 4 lifts (an overlap of 1 to 3 spans), the first 0, the last > 0",
                sm.marks["overlap_lift"],
            )
        n_o = len(lift) - 1
        lo = _count(r, sm, "spans_min", q, 2 * n_o + 1, 200)
        rule = dataclasses.replace(
            rule,
            section_spans_min=lo,
            section_spans_max=_count(r, sm, "spans_max", q, lo, 200),
            overlap_lift=lift,
        )
    if (rule.span_min - 2.0 * rule.end_dropper) / (rule.droppers - 1) < 1.0:
        raise r.fail(
            "layout.droppers",
            rule.droppers,
            "droppers at least 1 m apart in the shortest span",
            m.marks["droppers"],
        )
    return rule


def _deviation(r: Reader, raw: Map, data: CatenaryData) -> tuple[DeviationModel, int]:
    m, p = r.mapping(raw, "deviation", "", DEVIATION_KEYS), "deviation."
    model = DeviationModel(
        model=_choice(r, m, "model", p, DEVIATION_MODELS),
        vertical_sigma=r.number(m, "vertical_sigma", p, "m", 0.0, 0.05, low_open=False),
        correlation_length=r.number(m, "correlation_length", p, "m", 0.1, 1000.0),
        longitudinal_sigma=r.number(m, "longitudinal_sigma", p, "m", 0.0, 1.0, low_open=False),
    )
    if data.stitched:
        raise r.fail("deviation", "a stitched line", "a line without stitch wires", raw.marks["deviation"])
    spans = _count(r, m, "spans", p, 1, 1000, default=data.n_spans)
    return model, spans


def _span(r: Reader, s: Map, i: int) -> SpanData:
    p = f"spans[{i}]."
    r.known(s, p, SPAN_KEYS)
    length = r.number(s, "length", p, "m", 5.0, 200.0)
    encumbrance = r.number(s, "encumbrance", p, "m", 0.2, 5.0)
    droppers = r.numbers(s, "droppers", p, "m", -math.inf, math.inf, low_open=True, count=None)
    for j, d in enumerate(droppers):
        if not 0.0 < d < length:
            raise r.fail(
                f"{p}droppers[{j}]",
                d,
                f"a position in (0, {length:g}) m from the span's start",
                s.marks["droppers"],
            )
    _increasing(r, droppers, f"{p}droppers", s.marks["droppers"])
    presag = r.numbers(
        s, "presag", p, "m", -0.5 * encumbrance, 0.5 * encumbrance, low_open=False, count=len(droppers)
    )
    stitch = None
    if s.get("stitch") is not None:
        st = r.mapping(s, "stitch", p, STITCH_KEYS)
        q = f"{p}stitch."
        st_length = r.number(st, "length", q, "m", 1.0, 100.0)
        offsets = r.numbers(st, "droppers", q, "m", -math.inf, math.inf, low_open=True, count=None)
        for j, o in enumerate(offsets):
            if o == 0.0 or abs(o) >= 0.5 * st_length:
                raise r.fail(
                    f"{q}droppers[{j}]",
                    o,
                    f"an offset from the support in (-{0.5 * st_length:g}, 0) or (0, {0.5 * st_length:g}) m",
                    st.marks["droppers"],
                )
        _increasing(r, offsets, f"{q}droppers", st.marks["droppers"])
        stitch = StitchData(
            length=st_length,
            tension=r.number(st, "tension", q, "N", 0.0, 1e5),
            rho=r.number(st, "rho", q, "kg/m", 0.0, 10.0),
            dropper_offsets=offsets,
            presag=r.numbers(
                st,
                "presag",
                q,
                "m",
                -0.5 * encumbrance,
                0.5 * encumbrance,
                low_open=False,
                count=len(offsets),
            ),
        )
    return SpanData(length, encumbrance, droppers, presag, stitch)


def _increasing(r: Reader, values: tuple[float, ...], key: str, mark: tuple[int, int]) -> None:
    for j in range(1, len(values)):
        if values[j] <= values[j - 1]:
            raise r.fail(
                f"{key}[{j}]",
                values[j],
                f"a value above the one before it ({values[j - 1]:g}): ascending",
                mark,
            )


def _check_stitches(r: Reader, raw: Seq, spans: tuple[SpanData, ...]) -> None:
    """A stitch wire must end inside the spans next to its support (the period is cycled), and its
    droppers must not fall on the spans' own droppers."""
    n = len(spans)
    for i, span in enumerate(spans):
        st = span.stitch
        if st is None:
            continue
        before = spans[(i - 1) % n]
        key, mark = f"spans[{i}].stitch.length", raw[i]["stitch"].marks["length"]
        room = 0.5 * min(span.length, before.length)  # its clamps between the support and mid-span
        if 0.5 * st.length >= room:
            raise r.fail(key, st.length, f"less than the shorter neighbouring span ({2 * room:g} m)", mark)
        for j, o in enumerate(st.dropper_offsets):
            pos, own = (o, span) if o > 0 else (before.length + o, before)
            if any(abs(pos - d) < 1e-6 for d in own.dropper_positions):
                raise r.fail(
                    f"spans[{i}].stitch.droppers[{j}]",
                    o,
                    "an offset whose dropper does not fall on a dropper of the span",
                    raw[i]["stitch"].marks["droppers"],
                )


PRESETS = Presets(PRESET_FOLDER, DEFAULT, "catenary", __file__, "docs/catenary.md")


def preset_path(name: str) -> Path | None:
    """The shipped preset ``name`` (``config/catenaries/<name>.yaml`` of the repository holding this
    package, from its source tree or its install tree), or None."""
    return PRESETS.path(name)


def presets() -> list[str]:
    """The names of the shipped presets."""
    return PRESETS.names()


def resolve(catenary: str) -> Path:
    """The file ``catenary`` names: a path (with ``/`` or a .yaml/.yml ending) or a preset's name."""
    return PRESETS.resolve(catenary)


def load_catenary(catenary: str = DEFAULT) -> CatenaryFile:
    """Read and check a catenary file (a path or a preset's name); cached per file and its mtime."""
    return _load(*PRESETS.read(catenary))


@lru_cache(maxsize=32)
def _load(path: str, mtime_ns: int, size: int) -> CatenaryFile:
    data, numerics, drawing = _parse(PRESETS.text(path), path)
    return CatenaryFile(Path(path), data, numerics, drawing)
