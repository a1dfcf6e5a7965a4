"""Lumped pantographs: mass, spring and damper matrices, head DOF, input DOF.

A pantograph is data: ``load_pantograph(name_or_path)`` reads a pantograph file
(``pac_model.pantograph_file``, format in docs/catenary.md, "The pantograph file") into the chain
the FE line runs (``LumpedPantograph``) and the file itself (its uplift at a speed);
``head_first`` orders a chain as the rig measures it (head, actuator's mass, the rest).

Positions are heights [m], positive up, in the contact wire's frame (0 = contact wire
height at the supports). Internal springs join masses; ``ground_stiffness`` and
``ground_damping`` join a mass to the car roof (their rest positions are set by the
integrator at the start, so that the static state has no roof-spring force).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from pac_common.parameters import ParameterError
from pac_model.pantograph_file import DEFAULT, PantographFile, load_pantograph_file, table1_file
from pac_model.parameters import PantographParameters

from ..parameters import PlantOptions


@dataclass(frozen=True)
class LumpedPantograph:
    name: str
    mass: np.ndarray  # (n,) kg
    stiffness: np.ndarray  # (n, n) internal springs, N/m
    damping: np.ndarray  # (n, n) internal dampers and dampers to the roof, N s/m
    ground_stiffness: np.ndarray  # (n,) springs to the roof, N/m
    head: int  # DOF that touches the wire
    input: int  # DOF on which the uplift / actuator force acts

    @property
    def n(self) -> int:
        return len(self.mass)

    def static_positions(self, head_height: float, force: float) -> np.ndarray:
        """Positions with the head at ``head_height`` pressed by contact force ``force`` = uplift."""
        k = self.stiffness
        rest = [i for i in range(self.n) if i != self.head]
        f = np.zeros(self.n)
        f[self.input] += force
        z = np.zeros(self.n)
        z[self.head] = head_height
        z[rest] = np.linalg.solve(k[np.ix_(rest, rest)], f[rest] - k[rest, self.head] * head_height)
        return z


def lumped(chain: PantographFile) -> LumpedPantograph:
    """The ``LumpedPantograph`` of a pantograph file's chain (its matrices: ``PantographFile.matrices``)."""
    mass, stiffness, damping, roof = chain.matrices()
    return LumpedPantograph(
        name=chain.name,
        mass=mass,
        stiffness=stiffness,
        damping=damping,
        ground_stiffness=roof,
        head=chain.head,
        input=chain.actuator,
    )


def load_pantograph(pantograph: str = DEFAULT) -> tuple[LumpedPantograph, PantographFile]:
    """A pantograph file (a path or a preset's name, ``config/pantographs/``) as the chain the FE
    line runs with, and the file itself (its uplift: ``PantographFile.uplift(speed_kmh)``)."""
    chain = load_pantograph_file(pantograph)
    return lumped(chain), chain


def head_first(chain: LumpedPantograph) -> LumpedPantograph:
    """The same chain with its DOFs reordered (head, actuator's mass, the rest): the order in which
    the rig reads z1 (the head) and z2 (the mass the actuator drives, the paper's frame). The paper's
    chain is already in that order (returned as it is)."""
    if chain.head == chain.input:
        raise ParameterError(
            "pantograph",
            chain.name,
            "a chain whose actuator acts on another mass than the head (the rig measures both)",
        )
    order = [chain.head, chain.input] + [i for i in range(chain.n) if i not in (chain.head, chain.input)]
    if order == list(range(chain.n)):
        return chain
    ix = np.ix_(order, order)
    return LumpedPantograph(
        name=chain.name,
        mass=chain.mass[order],
        stiffness=chain.stiffness[ix],
        damping=chain.damping[ix],
        ground_stiffness=chain.ground_stiffness[order],
        head=0,
        input=1,
    )


def plant_chain(
    pantograph: PantographParameters, options: PlantOptions, speed_kmh: float
) -> tuple[PantographFile, float]:
    """The plant's pantograph and its own mean uplift [N]: the file ``options.pantograph`` names,
    else the nominal pantograph's chain (``pantograph``'s m1, b1, k1, m2, b2, with the uplift of its
    ``nominal_pantograph`` file if any); the uplift is the file's at ``speed_kmh`` (static +
    aerodynamic).

    The controlled pantograph's own uplift is *not* a force added to the command: the command u is
    the whole force on the actuator's mass, as in the paper (eq. (5)), and the pantograph's uplift is
    the static part of it that its actuator holds (``actuator_static_force``) and a passive law
    commands. Adding it to u would press a pantograph with a file uplift twice (the passive law on
    the 3-mass pantograph at 300 km/h delivered a mean 298 N for a reference of 157 N). It sets the
    turbulent uplift's scale and the roof springs' rest; only ``wind_uplift`` acts with u."""
    if options.pantograph:
        chain = load_pantograph_file(options.pantograph)
        pressed_by = chain
    else:
        chain = table1_file(pantograph)
        named = pantograph.nominal_pantograph
        pressed_by = load_pantograph_file(named, "nominal_pantograph") if named else chain
    return chain, pressed_by.uplift(speed_kmh)


def paper_pantograph(p: PantographParameters | None = None) -> LumpedPantograph:
    """The paper's 2-DOF pantograph (Fig. 2, Table 1, eqs. 3-4): DOFs (z1 head, z2 frame).

    k1, b1 join head and frame; b2 damps the frame to the car body (no spring: the
    static uplift comes from the actuator force u on the frame). The same chain as the preset
    ``config/pantographs/paper_2dof.yaml`` (``table1_file``).
    """
    return dataclasses.replace(
        lumped(table1_file(PantographParameters() if p is None else p)), name="paper 2-DOF (Table 1)"
    )


def three_mass_pantograph(
    masses: tuple[float, float, float] = (6.0, 9.0, 7.5),
    stiffnesses: tuple[float, float, float] = (160.0, 15500.0, 7000.0),
    dampings: tuple[float, float, float] = (100.0, 0.0, 0.0),
) -> LumpedPantograph:
    """Benchmark-like 3-mass pantograph of docs/catenary_data.md §2, DOFs (frame, upper frame, head).

    Our reading of the unconfirmed arrangement, in the order the data lists them
    (roof -> frame -> upper frame -> head): masses 6.0 (frame), 9.0 (upper frame),
    7.5 kg (head); springs 160 N/m roof-frame, 15500 N/m frame-upper frame, 7000 N/m
    upper frame-head; dampers 100 N s/m roof-frame (the typical order the data
    quotes), none between the masses (none is stated). The static uplift acts on the frame.
    The preset ``config/pantographs/three_mass.yaml`` states the same chain (with its uplift).
    """
    links = ((0, -1), (0, 1), (1, 2))
    chain = PantographFile(
        name="3-mass (benchmark-like)",
        source="docs/catenary_data.md section 2",
        mass_names=("frame", "upper_frame", "head"),
        masses=tuple(masses),
        springs=tuple((i, j, k) for (i, j), k in zip(links, stiffnesses, strict=True)),
        dampers=tuple((i, j, c) for (i, j), c in zip(links, dampings, strict=True) if c != 0.0),
        head=2,
        actuator=0,
        static_uplift=0.0,
    )
    return lumped(chain)
