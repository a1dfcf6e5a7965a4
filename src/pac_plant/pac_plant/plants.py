"""The plants a run can simulate, by ``catenary_model``: one registry of what each one is and can do.

Every place that asks "which plant?" asks this table, not the name: the parameter's choices, the
checks of the plant options, the plant node, the offline simulator, the campaigns and the
composition rules. A new plant is its module (a class taking ``(pantograph, track, catenary,
options, sample_period)``, as :class:`pac_plant.plant.Plant` does) and one line in :data:`PLANTS`;
its module is imported only when a run chooses it (the FE line's modules cost a lumped plant node
~0.2 s of start-up otherwise).
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from pac_common.parameters import ParameterError

if TYPE_CHECKING:
    from pac_model.parameters import CatenaryParameters, PantographParameters, TrackParameters

# The plant classes and PlantOptions are not imported here, not even for types: the parameters
# read this table for their choices, and the plant modules import the parameters.


@dataclass(frozen=True)
class PlantKind:
    """One plant: where its class is and what it can do."""

    name: str
    #: "module:Class", imported when a run chooses this plant
    target: str
    #: The line is the catenary file's (``catenary``): its span, not ``span_length``, is the run's.
    line_from_file: bool
    #: It carries several pantographs (``pantographs``), each with its own contact.
    several_pantographs: bool
    #: Its pantograph must have the paper's 2-DOF shape (eq. (5)): a file is checked against Table 1.
    paper_pantograph_shape: bool
    #: What it is, for the ``catenary_model`` parameter's help ("'name' description; ...").
    description: str
    #: The module of its compiled parts (plant_kernels' protocol: ``<name>_output``, ``_advance``,
    #: ``_pack``), which the compiled loop reaches through the generated ``plant_dispatch``; None:
    #: it runs in the Python loop only (``closed_loop.run_cores``).
    kernel: str | None = None

    def plant_class(self) -> Any:
        """The plant's class (a ``pac_plant.plant.Plant``), its module imported now."""
        module, name = self.target.split(":")
        return getattr(importlib.import_module(module), name)


#: Every plant, by the ``catenary_model`` that chooses it.
PLANTS: dict[str, PlantKind] = {
    kind.name: kind
    for kind in (
        PlantKind(
            "lumped",
            "pac_plant.plant:Plant",
            False,
            False,
            True,
            "k(t) = k0 (1 + alpha cos(omega t - beta)) of eq. (7)",
            "pac_plant.lumped_kernels",
        ),
        PlantKind(
            "fe",
            "pac_plant.fe_plant:FEPlant",
            True,
            True,
            False,
            "the finite-element line of the file 'catenary' (docs/catenary.md; endless moving window; "
            "ignores k0/alpha/beta/span_length and contact_model: its contact is always unilateral)",
            "pac_plant.fe_kernels",
        ),
    )
}

#: Plant name -> its code in the compiled loop's ``PLANT_PARAMS.kind`` (the registry's order,
#: compiled plants only).
PLANT_CODES = {name: code for code, name in enumerate(n for n, kind in PLANTS.items() if kind.kernel)}


def plant_help() -> str:
    """The ``catenary_model`` parameter's help: each registered plant and what it is."""
    return "catenary: " + "; ".join(f"'{name}' {kind.description}" for name, kind in PLANTS.items())


def plant_kind(catenary_model: str) -> PlantKind:
    """The registry's entry for ``catenary_model`` (checked against :data:`PLANTS` by the
    parameter's choices before any run)."""
    return PLANTS[catenary_model]


def make_plant(
    pantograph: PantographParameters,
    track: TrackParameters,
    catenary: CatenaryParameters | None,
    options: Any,
    sample_period: float,
    pair_unit: bool = False,
) -> Any:
    """The plant (a ``pac_plant.plant.Plant``) that ``options.catenary_model`` (``PlantOptions``)
    names, its module imported now. ``all_pantographs_active`` is refused (one line) unless the plant
    is a unit of a pair loop (``pair_unit``): a rig of one unit would run the others passive."""
    if getattr(options, "all_pantographs_active", False) and not pair_unit:
        raise ParameterError(
            "all_pantographs_active",
            True,
            "false in a rig of one unit (its other pantographs are passive; both of a pair active run "
            "offline: pac_rig.pair_loop, make realistic-pair)",
        )
    cls = plant_kind(options.catenary_model).plant_class()
    return cls(pantograph, track, catenary, options, sample_period)


def compiled_plant(plant: Any) -> PlantKind | None:
    """The registry's entry of ``plant`` (by its exact class) if it has compiled parts, else None."""
    for kind in PLANTS.values():
        if kind.kernel is not None and type(plant) is kind.plant_class():
            return kind
    return None


def several_pantograph_models() -> tuple[str, ...]:
    """The ``catenary_model`` values whose plant carries several pantographs (for messages)."""
    return tuple(name for name, kind in PLANTS.items() if kind.several_pantographs)
