"""What defines a run, as parameter sets (:class:`Scenario`), and as flat parameter names.

The flat form is what ``-p NAME:=VALUE``, params files, campaign points and scenario files give;
:func:`from_flat` builds a :class:`Scenario` from it (``simulate.scenario_from_flat`` expands a
scenario file first). Its own module, so that the scenario file's checks need nothing that
builds or runs the cores.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field, replace
from typing import Any

from pac_common.parameters import LoopParameters, ParameterError, ParameterSet, parameter
from pac_controller.parameters import ControllerParameters, LawParameters, ReferenceParameters
from pac_model.parameters import CatenaryParameters, PantographParameters, TrackParameters
from pac_observer.parameters import ObserverParameters
from pac_plant.parameters import PlantOptions


@dataclass(frozen=True)
class ModelMismatch(ParameterSet):
    """Offline only: how the simulated pantograph differs from the one the observer and controller assume."""

    plant_mass_scale: float = parameter(
        1.0, "plant's m1 and m2 scaled by this (observer and controller keep Table 1's)", low=0.1, high=10.0
    )

    def plant_pantograph(self, nominal: PantographParameters) -> PantographParameters:
        return replace(nominal, m1=nominal.m1 * self.plant_mass_scale, m2=nominal.m2 * self.plant_mass_scale)


@dataclass(frozen=True)
class Scenario:
    """Everything that defines a run."""

    pantograph: PantographParameters = field(default_factory=PantographParameters)
    track: TrackParameters = field(default_factory=TrackParameters)
    catenary: CatenaryParameters = field(default_factory=CatenaryParameters)
    plant: PlantOptions = field(default_factory=PlantOptions)
    observer: ObserverParameters = field(default_factory=ObserverParameters)
    controller: ControllerParameters = field(default_factory=ControllerParameters)
    reference: ReferenceParameters = field(default_factory=ReferenceParameters)
    laws: LawParameters = field(default_factory=LawParameters)  # pid / lqr design (controller.law)
    loop: LoopParameters = field(default_factory=LoopParameters)
    mismatch: ModelMismatch = field(default_factory=ModelMismatch)


def scenario_sets(s: Scenario) -> dict[str, ParameterSet]:
    return {f.name: getattr(s, f.name) for f in dataclasses.fields(s)}


def scenario_to_flat(s: Scenario) -> dict[str, Any]:
    flat: dict[str, Any] = {}
    for pset in scenario_sets(s).values():
        flat.update(pset.as_dict())
    return flat


def from_flat(values: dict[str, Any], base: Scenario | None = None) -> Scenario:
    """A scenario with ``values`` (flat parameter names) over ``base``; unknown names are errors."""
    base = base or Scenario()
    known: set[str] = set()
    updated: dict[str, Any] = {}
    for name, pset in scenario_sets(base).items():
        names = {spec.name for spec in pset.specs()}
        known |= names
        mine = {k: v for k, v in values.items() if k in names}
        updated[name] = dataclasses.replace(pset, **mine) if mine else pset
    unknown = sorted(set(values) - known)
    if unknown:
        raise ParameterError(unknown[0], values[unknown[0]], "a known parameter name (see --list)")
    return Scenario(**updated)
