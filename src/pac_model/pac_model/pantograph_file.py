"""The pantograph file (YAML): a lumped chain of masses, springs and dampers, and its uplift.

Format, with one complete example: docs/catenary.md, "The pantograph file". The shipped presets
are ``config/pantographs/<name>.yaml``; ``pantograph:=NAME`` names one of them, anything with a
``/`` or a ``.yaml`` / ``.yml`` ending is a path. Every value is checked before anything is
built; a bad file raises :class:`PantographFileError`, one line naming the file, the line and
column, the key, the value and what is allowed (a ``ParameterError``: the tools exit 2).

The chain: masses (kg) joined to each other or to the car roof (``roof``, fixed) by springs
(N/m) and dampers (N s/m); ``head`` is the mass that touches the contact wire; ``actuator`` the
mass on which the actuator force u, the static uplift and the aerodynamic uplift act. The mean
uplift at speed v [km/h] is

    F_up(v) = static_uplift + c0 + c2 v^2                                   (aerodynamic part: c0 + c2 v^2)

the quadratic law of aerodynamic lift (dynamic pressure rho v^2 / 2 times an area and a lift
coefficient; docs/catenary.md, "The pantograph file", for the sources). The paper's 2-DOF
(Table 1, Fig. 2, eqs. 3-4) is the chain head -k1, b1- frame -b2- roof with u on the frame:
:meth:`PantographFile.table1` reads a file of that shape back into ``PantographParameters``.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from pac_common.data_file import DataFileError, Map, Presets, Reader, Seq
from pac_common.parameters import ParameterError

from .parameters import PantographParameters

DEFAULT = "paper_2dof"
PRESETS = Presets(Path("config") / "pantographs", DEFAULT, "pantograph", __file__, "docs/catenary.md")
#: Who needs the paper's 2-DOF shape (the refusal says so).
TABLE1_USERS = "the lumped plant and every observer and law are built on"
#: The car roof: the fixed end of springs and dampers (not a mass).
ROOF = "roof"
TOP_KEYS = (
    "name",
    "source",
    "masses",
    "springs",
    "dampers",
    "head",
    "actuator",
    "static_uplift",
    "aerodynamic_uplift",
)
MASS_KEYS = ("name", "mass")
SPRING_KEYS = ("between", "stiffness")
DAMPER_KEYS = ("between", "damping")
AERO_KEYS = ("c0", "c2")


class PantographFileError(DataFileError):
    """A pantograph file that cannot be used; the message is one line."""

    KIND = "pantograph"


@dataclass(frozen=True)
class PantographFile:
    """What a pantograph file states. Indices are positions in ``masses``; -1 is the roof."""

    name: str
    source: str
    mass_names: tuple[str, ...]
    masses: tuple[float, ...]  # kg
    springs: tuple[tuple[int, int, float], ...]  # (i, j, N/m), j = -1: to the roof
    dampers: tuple[tuple[int, int, float], ...]  # (i, j, N s/m)
    head: int
    actuator: int
    static_uplift: float  # N
    aero_c0: float = 0.0  # N
    aero_c2: float = 0.0  # N/(km/h)^2
    path: str = ""

    @property
    def n(self) -> int:
        return len(self.masses)

    def uplift(self, speed_kmh: float) -> float:
        """Mean uplift at ``speed_kmh`` [N]: static + c0 + c2 v^2 (v in km/h, as EN 50367's Fm(v))."""
        return self.static_uplift + (self.aero_c0 + self.aero_c2 * speed_kmh**2)

    def matrices(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(mass, stiffness, damping, roof stiffness): diag masses (n,), the springs between masses
        (n, n), every damper (between masses and to the roof, (n, n)), the springs to the roof (n,)."""
        n = self.n
        k, c, k_roof = np.zeros((n, n)), np.zeros((n, n)), np.zeros(n)
        for i, j, value in self.springs:
            if j < 0:
                k_roof[i] += value
            else:
                _add_pair(k, i, j, value)
        for i, j, value in self.dampers:
            if j < 0:
                c[i, i] += value
            else:
                _add_pair(c, i, j, value)
        return np.array(self.masses), k, c, k_roof

    def table1_shape(self) -> str:
        """'' when the chain is the paper's 2-DOF shape (head -spring, damper- frame -damper-
        roof, actuator on the frame, no roof spring, no head-roof damper), else why not."""
        if self.n != 2:
            return f"the paper's 2-DOF chain (2 masses; this one has {self.n})"
        if self.actuator == self.head:
            return "the paper's 2-DOF chain (the actuator on the frame, not the head)"
        if any(j < 0 for _, j, _ in self.springs):
            return "the paper's 2-DOF chain (no spring to the roof)"
        if any(j < 0 and i == self.head for i, j, _ in self.dampers):
            return "the paper's 2-DOF chain (no damper between the head and the roof)"
        return ""

    def table1(self, parameter: str = "pantograph") -> PantographParameters:
        """The paper's parameters m1, b1, k1, m2, b2 of a 2-DOF file (Table 1's symbols); a chain of
        another shape: ParameterError naming ``parameter`` (one line)."""
        why = self.table1_shape()
        if why:
            raise ParameterError(parameter, self.path or self.name, f"{why}, which {TABLE1_USERS}")
        frame = self.actuator
        k1 = sum(v for _, j, v in self.springs)
        b1 = sum(v for _, j, v in self.dampers if j >= 0)
        b2 = sum(v for _, j, v in self.dampers if j < 0)
        return PantographParameters(m1=self.masses[self.head], b1=b1, k1=k1, m2=self.masses[frame], b2=b2)


def table1_file(p: PantographParameters) -> PantographFile:
    """The paper's 2-DOF chain with the parameters ``p`` (Table 1's by default): the chain of the
    preset ``paper_2dof`` (masses head, frame; k1 and b1 between them, b2 frame-roof)."""
    return PantographFile(
        name="paper_2dof",
        source="Table 1 parameters m1, b1, k1, m2, b2",
        mass_names=("head", "frame"),
        masses=(p.m1, p.m2),
        springs=((0, 1, p.k1),),
        dampers=((0, 1, p.b1), (1, -1, p.b2)),
        head=0,
        actuator=1,
        static_uplift=0.0,
    )


def _add_pair(m: np.ndarray, i: int, j: int, value: float) -> None:
    """A spring or damper ``value`` between DOFs i and j added to the symmetric matrix ``m``."""
    m[i, i] += value
    m[j, j] += value
    m[i, j] -= value
    m[j, i] -= value


def parse_pantograph(text: str, source: str) -> PantographFile:
    """The ``PantographFile`` of a pantograph file's text (``source`` names it)."""
    r = Reader(source, PantographFileError)
    raw = r.parse(text, TOP_KEYS)
    name, described = r.text(raw, "name"), r.text(raw, "source")
    masses_raw = _items(r, raw, "masses", MASS_KEYS, required=True)
    names: list[str] = []
    masses: list[float] = []
    for i, m in enumerate(masses_raw):
        key = f"masses[{i}]."
        label = m.get("name")
        if not isinstance(label, str) or not label.strip() or label == ROOF or label in names:
            raise r.fail(
                f"{key}name",
                label,
                f"a non-empty name, not '{ROOF}' (the car roof), not given before",
                m.marks.get("name", m.start),
            )
        names.append(label)
        masses.append(r.number(m, "mass", key, "kg", 0.0, 1000.0))
    springs = _links(r, raw, "springs", "stiffness", "N/m", 1e8, names)
    dampers = _links(r, raw, "dampers", "damping", "N s/m", 1e6, names)
    head, actuator = (_mass(r, raw, key, names) for key in ("head", "actuator"))
    _check_held(r, raw, springs, names, head, actuator)
    aero = r.mapping(raw, "aerodynamic_uplift", "", AERO_KEYS, optional=True)
    return PantographFile(
        name=name,
        source=described,
        mass_names=tuple(names),
        masses=tuple(masses),
        springs=springs,
        dampers=dampers,
        head=head,
        actuator=actuator,
        static_uplift=r.number(raw, "static_uplift", "", "N", 0.0, 1000.0, low_open=False),
        aero_c0=r.number(aero, "c0", "aerodynamic_uplift.", "N", -500.0, 500.0, low_open=False, default=0.0),
        aero_c2=r.number(
            aero, "c2", "aerodynamic_uplift.", "N/(km/h)^2", -0.01, 0.01, low_open=False, default=0.0
        ),
        path=source,
    )


def _items(r: Reader, raw: Map, key: str, keys: tuple[str, ...], required: bool) -> list[Map]:
    value = raw.get(key)
    if value is None and not required:
        return []
    what = f"a {'non-empty ' if required else ''}list of mappings with {', '.join(keys)}"
    if not isinstance(value, Seq) or (required and not value) or not all(isinstance(v, Map) for v in value):
        raise r.fail(key, value, what, raw.marks.get(key, raw.start))
    for i, item in enumerate(value):
        r.known(item, f"{key}[{i}].", keys)
    return list(value)


def _links(
    r: Reader, raw: Map, key: str, quantity: str, unit: str, high: float, names: list[str]
) -> tuple[tuple[int, int, float], ...]:
    """Springs or dampers: each ``between`` two different masses, or a mass and the roof."""
    out = []
    ends = f"two different names among {', '.join(names)}, {ROOF}"
    for i, item in enumerate(_items(r, raw, key, ("between", quantity), required=False)):
        pair = item.get("between")
        mark = item.marks.get("between", item.start)
        if (
            not isinstance(pair, Seq)
            or len(pair) != 2
            or not all(isinstance(p, str) and (p in names or p == ROOF) for p in pair)
            or pair[0] == pair[1]
        ):
            raise r.fail(f"{key}[{i}].between", pair, ends, mark)
        a, b = (names.index(p) if p != ROOF else -1 for p in pair)
        value = r.number(item, quantity, f"{key}[{i}].", unit, 0.0, high, low_open=quantity == "stiffness")
        out.append((max(a, b), min(a, b), value) if min(a, b) < 0 else (a, b, value))
    return tuple(out)


def _mass(r: Reader, raw: Map, key: str, names: list[str]) -> int:
    value = raw.get(key)
    if value not in names:
        raise r.fail(key, value, f"one of the masses: {', '.join(names)}", raw.marks.get(key, raw.start))
    return names.index(value)


def _check_held(
    r: Reader,
    raw: Map,
    springs: tuple[tuple[int, int, float], ...],
    names: list[str],
    head: int,
    actuator: int,
) -> None:
    """Every mass must hang by springs from the head (held by the wire) or the roof: else its
    static position is undefined (a free body; the static equilibrium has no solution); and the
    head's springs must reach the actuator's mass (else the uplift never presses the wire)."""
    held = _reached({head, -1}, springs)  # from the wire and the roof
    loose = [n for i, n in enumerate(names) if i not in held]
    if loose:
        raise r.fail(
            "springs",
            loose[0],
            "a chain in which every mass is joined by springs to the head or the roof",
            raw.marks.get("springs", raw.start),
        )
    if actuator not in _reached({head}, springs):
        raise r.fail(
            "springs",
            names[head],
            f"springs that join the head to the actuator's mass ({names[actuator]}): "
            "its uplift must reach the wire",
            raw.marks.get("springs", raw.start),
        )


def _reached(start: set[int], springs: tuple[tuple[int, int, float], ...]) -> set[int]:
    """The masses joined by springs to ``start`` (-1: the roof, passed through only if in it)."""
    out, grew = set(start), True
    while grew:
        joined = {i for i, j, _ in springs if j in out} | {j for i, j, _ in springs if i in out and j >= 0}
        grew = not joined <= out
        out |= joined
    return out


def presets() -> list[str]:
    """The names of the shipped presets."""
    return PRESETS.names()


def load_pantograph_file(pantograph: str = DEFAULT, parameter: str = "pantograph") -> PantographFile:
    """Read and check a pantograph file (a path or a preset's name; ``parameter``: the parameter
    that named it, for the error line); cached per file and its mtime."""
    return _load(*PRESETS.read(pantograph, parameter))


@lru_cache(maxsize=32)
def _load(path: str, mtime_ns: int, size: int) -> PantographFile:
    return parse_pantograph(PRESETS.text(path), path)
