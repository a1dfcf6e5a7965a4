"""The catenary and pantograph data of docs/catenary_data.md §2 (benchmark-like, unconfirmed).

Plain frozen dataclasses: the values are the stated data set; only the numerical
choices (element size, time step, penalty, damping) are meant to be varied.
"""

from __future__ import annotations

from dataclasses import dataclass

GRAVITY = 9.81  # m/s^2


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
class CatenaryData:
    """Simple catenary of docs/catenary_data.md §2 (values as stated there)."""

    span: float = 55.0
    n_spans: int = 10
    system_height: float = 1.2
    contact: WireData = WireData(1.35, 22000.0, 195.0)
    messenger: WireData = WireData(1.08, 16000.0, 131.7)
    dropper_positions: tuple[float, ...] = (4.5, 10.25, 16.0, 21.75, 27.5, 33.25, 39.0, 44.75, 50.5)
    presag: tuple[float, ...] = (0.0, 0.024, 0.041, 0.052, 0.055, 0.052, 0.041, 0.024, 0.0)
    dropper_ea: float = 200e3  # N
    dropper_rho: float = 0.117  # kg/m
    clamp_mass_messenger: float = 0.195  # kg
    clamp_mass_contact: float = 0.165  # kg
    steady_arm_stiffness: float = 2673.58  # N/m
    messenger_support_stiffness: float = 500e3  # N/m
    gravity: float = GRAVITY


@dataclass(frozen=True)
class NumericalOptions:
    """Discretisation and damping choices (docs/catenary.md: convergence study, damping, penalty)."""

    element_size: float = 0.5  # m, upper bound: each dropper interval is split into equal elements
    #: Rayleigh damping C = alpha M + beta K of the line (the values the benchmark reproductions use).
    rayleigh_alpha: float = 0.0125  # 1/s
    rayleigh_beta: float = 1.0e-4  # s
    #: Penalty contact stiffness (the benchmark's 50 kN/m).
    contact_stiffness: float = 50e3  # N/m
