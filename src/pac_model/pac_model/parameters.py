"""Parameter sets of the pantograph-catenary model (Table 1 of the paper)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pac_common.parameters import ParameterError, ParameterSet, parameter


def positive_period(value: float, name: str = "sample_period") -> float:
    """``value`` when it is a finite time step > 0 [s]; else ValueError naming it. Every core
    (plant, observer, controller, law, FE integrator) checks its step here."""
    if not (math.isfinite(value) and value > 0.0):
        raise ValueError(f"{name} must be positive, got {value!r}")
    return value


@dataclass(frozen=True)
class PantographParameters(ParameterSet):
    """Lumped 2-DOF pantograph (Fig. 2, Table 1). Known to the observer and controller."""

    m1: float = parameter(8.0, "pantograph head (upper frame) mass", "kg", low=0.0, low_open=True)
    b1: float = parameter(120.0, "head suspension damping", "N*s/m", low=0.0, low_open=True)
    k1: float = parameter(10000.0, "head suspension stiffness", "N/m", low=0.0, low_open=True)
    m2: float = parameter(12.0, "lower frame mass", "kg", low=0.0, low_open=True)
    b2: float = parameter(30.0, "lower frame damping to the car body", "N*s/m", low=0.0)
    nominal_pantograph: str = parameter(
        "",
        "the pantograph the observer and controller are told, as a pantograph file (a path) or a "
        "preset's name (config/pantographs/: paper_2dof, ...): its chain must have the paper's 2-DOF "
        "shape and replaces m1, b1, k1, m2, b2 (also the plant's pantograph unless the plant's "
        "'pantograph' names another); '' = m1, b1, k1, m2, b2 as given. Format: docs/catenary.md, "
        "'The pantograph file'",
    )

    def check_consistency(self) -> None:
        """A ``nominal_pantograph`` file states m1, b1, k1, m2, b2: they take its values (a value also
        given here must be Table 1's default or the file's: never two answers)."""
        if not self.nominal_pantograph:
            return
        from .pantograph_file import load_pantograph_file  # the file module reads YAML: only when asked

        stated = PantographParameters(
            **load_pantograph_file(self.nominal_pantograph, "nominal_pantograph").table1("nominal_pantograph")
        )
        for spec in PantographParameters.specs():
            if spec.name == "nominal_pantograph":
                continue
            given, value = getattr(self, spec.name), getattr(stated, spec.name)
            if given not in (spec.default, value):
                raise ParameterError(
                    spec.name, given, f"{value:g} or unset: the file nominal_pantograph states it"
                )
            object.__setattr__(self, spec.name, value)


@dataclass(frozen=True)
class TrackParameters(ParameterSet):
    """Vehicle speed and span length: they set the stiffness frequency omega of eq. (2).

    Known to the observer and controller (v(t) of eq. (9) needs omega).
    """

    speed_kmh: float = parameter(360.0, "vehicle speed lambda", "km/h", low=0.0, low_open=True, high=600.0)
    span_length: float = parameter(65.0, "catenary span length L", "m", low=0.0, low_open=True)

    @property
    def omega(self) -> float:
        """omega = 2 pi lambda / L, eq. (2) [rad/s]."""
        return 2.0 * math.pi * (self.speed_kmh / 3.6) / self.span_length


@dataclass(frozen=True)
class CatenaryParameters(ParameterSet):
    """Catenary stiffness k(t) = k0 (1 + alpha cos(omega t - beta)), eqs. (2)/(7).

    Unknown to the observer and the controller: only the plant uses these.
    """

    k0: float = parameter(4000.0, "average catenary stiffness", "N/m", low=0.0, low_open=True)
    alpha: float = parameter(
        0.5, "stiffness variation coefficient", "", low=-1.0, high=1.0, low_open=True, high_open=True
    )
    beta: float = parameter(math.pi / 4, "stiffness phase at t = 0", "rad", low=-math.pi, high=math.pi)

    @property
    def theta(self) -> np.ndarray:
        """theta = (k0, k0 alpha cos beta, k0 alpha sin beta), eq. (9) [N/m]."""
        return np.array(
            [
                self.k0,
                self.k0 * self.alpha * math.cos(self.beta),
                self.k0 * self.alpha * math.sin(self.beta),
            ]
        )
