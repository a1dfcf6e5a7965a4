"""Lumped pantographs: mass, spring and damper matrices, head DOF, input DOF.

Positions are heights [m], positive up, in the contact wire's frame (0 = contact wire
height at the supports). Internal springs join masses; ``ground_stiffness`` and
``ground_damping`` join a mass to the car roof (their rest positions are set by the
integrator at the start, so that the static state has no roof-spring force).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pac_model.parameters import PantographParameters


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


def _pair(n: int, a: int, b: int, value: float) -> np.ndarray:
    m = np.zeros((n, n))
    m[a, a] = m[b, b] = value
    m[a, b] = m[b, a] = -value
    return m


def paper_pantograph(p: PantographParameters | None = None) -> LumpedPantograph:
    """The paper's 2-DOF pantograph (Fig. 2, Table 1, eqs. 3-4): DOFs (z1 head, z2 frame).

    k1, b1 join head and frame; b2 damps the frame to the car body (no spring: the
    static uplift comes from the actuator force u on the frame).
    """
    p = PantographParameters() if p is None else p
    c = _pair(2, 0, 1, p.b1)
    c[1, 1] += p.b2
    return LumpedPantograph(
        name="paper 2-DOF (Table 1)",
        mass=np.array([p.m1, p.m2]),
        stiffness=_pair(2, 0, 1, p.k1),
        damping=c,
        ground_stiffness=np.zeros(2),
        head=0,
        input=1,
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
    """
    m1, m2, m3 = masses
    k_roof, k12, k23 = stiffnesses
    c_roof, c12, c23 = dampings
    k = _pair(3, 0, 1, k12) + _pair(3, 1, 2, k23)
    c = _pair(3, 0, 1, c12) + _pair(3, 1, 2, c23)
    c[0, 0] += c_roof
    return LumpedPantograph(
        name="3-mass (benchmark-like)",
        mass=np.array([m1, m2, m3]),
        stiffness=k,
        damping=c,
        ground_stiffness=np.array([k_roof, 0.0, 0.0]),
        head=2,
        input=0,
    )
