"""The catenary file (YAML): reading and checking it into ``CatenaryData`` + ``NumericalOptions``.

Format, with one complete example: docs/catenary.md, "The catenary file". The shipped presets
are ``config/catenaries/<name>.yaml``; ``catenary:=NAME`` names one of them, anything with a
``/`` or a ``.yaml`` / ``.yml`` ending is a path.

Every value is checked before anything is built; a bad file raises :class:`CatenaryFileError`,
one line naming the file, the line and column, the key, the value and what is allowed (a
``ParameterError``: the nodes and tools print it and exit 2).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

import yaml

from pac_common.parameters import ParameterError

from .data import GRAVITY, CatenaryData, NumericalOptions, SpanData, StitchData, WireData

#: The shipped presets, in the repository (found from this file's location, installed or not).
PRESET_FOLDER = Path("config") / "catenaries"
DEFAULT = "benchmark_55m"


class CatenaryFileError(ParameterError):
    """A catenary file that cannot be used; the message is one line."""

    def __init__(self, source: str, key: str, value: Any, allowed: str, where: str = "") -> None:
        self.name = key
        self.value = value
        self.allowed = allowed
        ValueError.__init__(
            self, f"invalid catenary file '{source}'{where}: '{key}' = {value!r}: allowed {allowed}"
        )


@dataclass(frozen=True)
class CatenaryFile:
    """What a catenary file states: the line and the numerical options that go with it."""

    path: Path
    data: CatenaryData
    numerics: NumericalOptions


# -- YAML with positions --------------------------------------------------------------------------
class _Map(dict):
    """A mapping that knows where each of its values starts in the file."""

    marks: dict[Any, tuple[int, int]]
    start: tuple[int, int]


class _Seq(list):
    marks: list[tuple[int, int]]
    start: tuple[int, int]


def _mark(node: yaml.Node) -> tuple[int, int]:
    return node.start_mark.line + 1, node.start_mark.column + 1


class _Loader(yaml.SafeLoader):
    pass


class _DuplicateKey(Exception):
    def __init__(self, key: Any, mark: tuple[int, int]) -> None:
        self.key, self.mark = key, mark


def _construct_map(loader: _Loader, node: yaml.MappingNode) -> _Map:
    loader.flatten_mapping(node)
    out = _Map()
    out.marks, out.start = {}, _mark(node)
    for key_node, value_node in node.value:
        key = loader.construct_object(key_node, deep=True)
        if key in out:
            raise _DuplicateKey(key, _mark(key_node))
        out[key] = loader.construct_object(value_node, deep=True)
        out.marks[key] = _mark(value_node)
    return out


def _construct_seq(loader: _Loader, node: yaml.SequenceNode) -> _Seq:
    out = _Seq(loader.construct_object(child, deep=True) for child in node.value)
    out.marks, out.start = [_mark(child) for child in node.value], _mark(node)
    return out


_Loader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _construct_map)
_Loader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_SEQUENCE_TAG, _construct_seq)


# -- checking ---------------------------------------------------------------------------------------
class _Reader:
    """Reads values out of the parsed file, each check naming its key path and position."""

    def __init__(self, source: str) -> None:
        self.source = source

    def fail(self, key: str, value: Any, allowed: str, mark: tuple[int, int] | None) -> CatenaryFileError:
        where = f", line {mark[0]}, column {mark[1]}" if mark else ""
        return CatenaryFileError(self.source, key, value, allowed, where)

    def mapping(
        self, parent: _Map, name: str, path: str, keys: tuple[str, ...], optional: bool = False
    ) -> _Map:
        key = f"{path}{name}"
        if name not in parent:
            if optional:
                empty = _Map()
                empty.marks, empty.start = {}, getattr(parent, "start", (0, 0))
                return empty
            raise self.fail(key, None, f"a mapping with {', '.join(keys)} (it is missing)", parent.start)
        value = parent[name]
        if not isinstance(value, _Map):
            raise self.fail(key, value, f"a mapping with {', '.join(keys)}", parent.marks[name])
        self.known(value, key + ".", keys)
        return value

    def known(self, mapping: _Map, path: str, keys: tuple[str, ...]) -> None:
        for k in mapping:
            if k not in keys:
                raise self.fail(
                    f"{path}{k}", mapping[k], f"one of the keys {', '.join(keys)}", mapping.marks[k]
                )

    def number(
        self,
        parent: _Map,
        name: str,
        path: str,
        unit: str,
        low: float = 0.0,
        high: float = math.inf,
        *,
        low_open: bool = True,
        default: float | None = None,
    ) -> float:
        key = f"{path}{name}"
        if name not in parent:
            if default is not None:
                return default
            raise self.fail(
                key, None, f"{_range(low, high, low_open)} {unit} (it is missing)".strip(), parent.start
            )
        return self.check_number(parent[name], key, unit, low, high, low_open, parent.marks[name])

    def check_number(
        self, value: Any, key: str, unit: str, low: float, high: float, low_open: bool, mark: tuple[int, int]
    ) -> float:
        ok = isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
        if ok:
            ok = (value > low if low_open else value >= low) and value <= high
        if not ok:
            raise self.fail(
                key, value, f"a finite number in {_range(low, high, low_open)} {unit}".strip(), mark
            )
        return float(value)

    def numbers(
        self,
        parent: _Map,
        name: str,
        path: str,
        unit: str,
        low: float,
        high: float,
        *,
        low_open: bool,
        count: int | None,
    ) -> tuple[float, ...]:
        key = f"{path}{name}"
        size = "a non-empty list" if count is None else f"a list of {count}"
        what = f"{size} of finite numbers in {_range(low, high, low_open)} {unit}".strip()
        value = parent.get(name)
        if not isinstance(value, _Seq) or not value or (count is not None and len(value) != count):
            raise self.fail(key, value, what, parent.marks.get(name, parent.start))
        return tuple(
            self.check_number(v, f"{key}[{i}]", unit, low, high, low_open, m)
            for i, (v, m) in enumerate(zip(value, value.marks, strict=True))
        )


def _range(low: float, high: float, low_open: bool) -> str:
    left = "(" if low_open or low == -math.inf else "["
    right = ")" if high == math.inf else "]"
    return f"{left}{low:g}, {high:g}{right}"


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


def parse_catenary(text: str, source: str) -> tuple[CatenaryData, NumericalOptions]:
    """``CatenaryData`` and ``NumericalOptions`` of a catenary file's text (``source`` names it)."""
    r = _Reader(source)
    try:
        raw = yaml.load(text, Loader=_Loader)  # safe: _Loader is a SafeLoader
    except _DuplicateKey as exc:
        raise r.fail(str(exc.key), "given twice", "each key once", exc.mark) from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        problem = getattr(exc, "problem", None) or type(exc).__name__
        raise r.fail(
            "(YAML)", problem, "valid YAML", (mark.line + 1, mark.column + 1) if mark else None
        ) from None
    if not isinstance(raw, _Map):
        raise r.fail("(file)", raw, f"a mapping with the keys {', '.join(TOP_KEYS)}", None)
    r.known(raw, "", TOP_KEYS)
    for key in ("name", "source"):
        if not isinstance(raw.get(key), str) or not raw[key].strip():
            raise r.fail(key, raw.get(key), "a non-empty string", raw.marks.get(key, raw.start))
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
    spans_raw = raw.get("spans")
    if not isinstance(spans_raw, _Seq) or not spans_raw or not all(isinstance(s, _Map) for s in spans_raw):
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
    return data, options


def _span(r: _Reader, s: _Map, i: int) -> SpanData:
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


def _increasing(r: _Reader, values: tuple[float, ...], key: str, mark: tuple[int, int]) -> None:
    for j in range(1, len(values)):
        if values[j] <= values[j - 1]:
            raise r.fail(
                f"{key}[{j}]",
                values[j],
                f"a value above the one before it ({values[j - 1]:g}): ascending",
                mark,
            )


def _check_stitches(r: _Reader, raw: _Seq, spans: tuple[SpanData, ...]) -> None:
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


def preset_path(name: str) -> Path | None:
    """The shipped preset ``name`` (``config/catenaries/<name>.yaml`` of the repository holding this
    package, from its source tree or its install tree), or None."""
    for folder in Path(__file__).resolve().parents:
        candidate = folder / PRESET_FOLDER / f"{name}.yaml"
        if candidate.is_file():
            return candidate
    return None


def presets() -> list[str]:
    """The names of the shipped presets."""
    path = preset_path(DEFAULT)
    return sorted(p.stem for p in path.parent.glob("*.yaml")) if path else []


def resolve(catenary: str) -> Path:
    """The file ``catenary`` names: a path (with ``/`` or a .yaml/.yml ending) or a preset's name."""
    if "/" in catenary or catenary.endswith((".yaml", ".yml")):
        return Path(catenary)
    path = preset_path(catenary)
    if path is None:
        raise ParameterError(
            "catenary",
            catenary,
            f"a catenary file or a preset: one of {', '.join(presets())} (docs/catenary.md)",
        )
    return path


def load_catenary(catenary: str = DEFAULT) -> CatenaryFile:
    """Read and check a catenary file (a path or a preset's name); cached per file and its mtime."""
    path = resolve(catenary)
    try:
        stat = path.stat()
    except OSError as exc:
        raise ParameterError(
            "catenary", catenary, f"a readable catenary file ({exc.strerror or exc})"
        ) from None
    return _load(str(path), stat.st_mtime_ns, stat.st_size)


@lru_cache(maxsize=32)
def _load(path: str, mtime_ns: int, size: int) -> CatenaryFile:
    try:
        text = Path(path).read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise ParameterError("catenary", path, f"a readable catenary file ({exc})") from None
    data, numerics = parse_catenary(text, path)
    return CatenaryFile(Path(path), data, numerics)
