"""How the plant is simulated: options that are not part of the paper's model."""

from __future__ import annotations

from dataclasses import dataclass

from pac_common.parameters import ParameterError, ParameterSet, parameter

from .hardware.actuators import ACTUATORS
from .hardware.car_body import CAR_BODIES, TRACKS
from .hardware.sensors import SENSORS
from .plants import PLANTS, plant_help, plant_kind, several_pantograph_models

#: Pantographs on one FE line, and the largest distance between the first and the last [m]: the
#: moving window grows by that distance (its cost with it).
MAX_PANTOGRAPHS = 4
MAX_PANTOGRAPH_SPACING = 1000.0


@dataclass(frozen=True)
class PlantOptions(ParameterSet):
    """How the plant is simulated (not part of the paper's model)."""

    contact_model: str = parameter(
        "linear",
        "contact law: 'linear' F = k z1 (the paper's eq. (6), F may go negative), "
        "'unilateral' F = max(k z1, 0) (the head leaves the wire)",
        choices=("linear", "unilateral"),
    )
    noise_std: tuple = parameter(
        (0.0, 0.0),
        "standard deviation of the measurement noise on (z1, z2)",
        "m",
        length=2,
        low=0.0,
        high=0.1,
    )
    noise_seed: int = parameter(
        0, "seed of the measurement noise (the same seed gives the same noise)", low=0
    )
    quantisation: float = parameter(
        0.0, "position sensor resolution, 0 for none (measurements rounded to it)", "m", low=0.0, high=0.01
    )
    substeps: int = parameter(
        2, "RK4 steps per sample period (accuracy: see docs/numerics.md)", low=1, high=1000
    )
    catenary_model: str = parameter(
        "lumped",
        plant_help(),
        choices=tuple(PLANTS),
    )
    catenary: str = parameter(
        "benchmark_55m",
        "fe: the line, a catenary file (a path) or a shipped preset's name (config/catenaries/: "
        "benchmark_55m, ...); the file format is documented in docs/catenary.md, 'The catenary file'",
    )
    pantograph: str = parameter(
        "",
        "the simulated pantograph, a pantograph file (a path) or a shipped preset's name "
        "(config/pantographs/: paper_2dof, three_mass, ...): any chain of masses, springs and dampers "
        "with its static and aerodynamic uplift (the lumped plant takes the paper's 2-DOF shape only); "
        "'' = the nominal pantograph (m1, b1, k1, m2, b2 or nominal_pantograph). The file format is "
        "documented in docs/catenary.md, 'The pantograph file'",
    )
    wind_uplift: float = parameter(
        0.0,
        "steady wind uplift on the pantograph, added to the actuator force on the actuator's mass "
        "(0: no wind; docs/catenary.md, 'The pantograph file')",
        "N",
        low=-200.0,
        high=200.0,
    )
    actuator: str = parameter(
        "ideal",
        "the actuator between the command and the pantograph: 'ideal' the command is the force "
        "(today's rig); 'electromechanical' (+-100 N about actuator_static_force, 5 kN/s, lag 20 ms, "
        "delay 5 ms) or 'pneumatic' (+-100 N, 500 N/s, lag 200 ms, delay 20 ms); "
        "docs/vehicle_and_hardware.md gives each number's source",
        choices=tuple(ACTUATORS),
    )
    actuator_static_force: float = parameter(
        100.0,
        "the static force F0 the actuator's range is about (the pneumatic uplift a fast actuator acts "
        "on top of; set it to the run's force_amplitude, whose default it is); the actuator holds it "
        "at tick 0 (not used by 'ideal')",
        "N",
        low=0.0,
        high=1000.0,
    )
    roof_motion: str = parameter(
        "",
        "the car body moves: the pantograph's base rides on the roof of a car body in bounce and pitch "
        "over a seeded track of this irregularity class ('german_low' or 'german_high'); '' = a fixed "
        "base (today's rig); with several pantographs each rides on a car as far behind the first as it "
        "is, over the same track. docs/vehicle_and_hardware.md gives the model and its numbers",
        choices=("", *TRACKS),
    )
    roof_seed: int = parameter(0, "seed of the track under the car body (roof_motion)", low=0)
    car_body: str = parameter(
        "high_speed_trailer",
        "the car body whose roof carries the pantograph (roof_motion; docs/vehicle_and_hardware.md)",
        choices=tuple(CAR_BODIES),
    )
    aero_turbulence: float = parameter(
        0.0,
        "turbulent uplift: RMS of a seeded fluctuation of the pantograph's mean uplift (static + "
        "aerodynamic + wind), as a fraction of it, flat over 0.5-20 Hz (0: none, today's; 0.05-0.1 is "
        "the judgement of docs/vehicle_and_hardware.md)",
        low=0.0,
        high=0.5,
    )
    aero_turbulence_seed: int = parameter(0, "seed of the turbulent uplift (aero_turbulence)", low=0)
    sensors: str = parameter(
        "ground",
        "the sensor suite: 'ground' z1, z2 from a fixed datum with noise_std and quantisation "
        "(today's rig); 'train' head and frame positions from the roof and head and frame "
        "accelerometers, 'train_load_cell' also a head load cell, each channel with noise, bandwidth "
        "and latency (seeded by noise_seed; docs/vehicle_and_hardware.md gives each number's source)",
        choices=tuple(SENSORS),
    )
    fe_substeps: int = parameter(
        1, "fe: Newmark steps per sample period (docs/catenary.md: convergence)", low=1, high=20
    )
    fe_datum: str = parameter(
        "fixed",
        "fe: what z1, z2 are measured from: 'fixed' the static contact-wire height at the start "
        "support (what a rig measures); 'static_wire' the static (pre-sagged) contact-wire height "
        "under the current contact point (the line's design sag subtracted by position)",
        choices=("fixed", "static_wire"),
    )
    fe_element_size: float = parameter(
        0.5, "fe: largest beam element length (docs/catenary.md: convergence)", "m", low=0.1, high=2.0
    )

    fe_window_spans: float = parameter(
        0.0,
        "fe: a moving window on a whole line: each step works on this many mean spans around the "
        "pantographs (plus their spacing) and holds the rest of the line at rest (0: the whole "
        "line; not on an endless line; docs/catenary.md: A moving window)",
        low=0.0,
        high=1000.0,
    )

    fe_height_error: float = parameter(
        0.0,
        "fe: standard deviation of the contact-wire height error at each dropper (0: none; seeded by "
        "fe_imperfection_seed; drawn over 10 spans, repeating on the endless line; docs/catenary.md: "
        "Imperfections)",
        "m",
        low=0.0,
        high=0.05,
    )
    fe_wear: float = parameter(
        0.0,
        "fe: fraction of the contact wire's section worn away (mass x (1 - wear), EI x (1 - wear)^2; "
        "0: new wire)",
        low=0.0,
        high=0.5,
    )
    fe_imperfection_seed: int = parameter(
        0, "fe: seed of the height errors (the same seed gives the same line)", low=0
    )
    line_seed: int = parameter(
        -1,
        "fe: seed of a drawn line, a catenary file with a layout rule or a deviation model (-1: the "
        "file's line_seed; the same seed gives the same line; docs/catenary.md, 'A whole line')",
        low=-1,
        high=2**32 - 1,
    )

    pantographs: tuple = parameter(
        (0.0,),
        "fe: the pantographs on the line, each one's distance behind the first (0: one pantograph; "
        "0, 200: a second, passive one 200 m behind; increasing; the window grows by the spacing, "
        "docs/catenary.md: Several pantographs)",
        "m",
        low=0.0,
        high=MAX_PANTOGRAPH_SPACING,
        max_length=MAX_PANTOGRAPHS,
    )
    controlled_pantograph: int = parameter(
        0,
        "fe: which of 'pantographs' (0: the first) the rig controls, the one observer and controller "
        "see; every other one is passive",
        low=0,
        high=MAX_PANTOGRAPHS - 1,
    )
    all_pantographs_active: bool = parameter(
        False,
        "fe: every one of 'pantographs' has its own actuator, sensors, observer and law (run offline "
        "by pac_rig.pair_loop; this rig is the one of controlled_pantograph): a law behind an "
        "active one runs passive until that one's learning has settled (docs/laws.md)",
    )
    passive_pantograph: str = parameter(
        "three_mass",
        "fe: the passive pantographs, a pantograph file (a path) or a shipped preset's name "
        "(config/pantographs/: three_mass, paper_2dof, ...; docs/catenary.md, 'The pantograph file')",
    )
    passive_pantograph_uplift: float = parameter(
        0.0,
        "fe: constant uplift force on each passive pantograph (0: its file's uplift at the track speed, "
        "static + aerodynamic; the wind_uplift acts too)",
        "N",
        low=0.0,
        high=500.0,
    )

    @property
    def drawn_line_seed(self) -> int | None:
        """The seed a catenary file's line is drawn with (``CatenaryFile.line``, ``design_supports``):
        ``line_seed``, or None for the file's own (-1)."""
        return None if self.line_seed < 0 else self.line_seed

    def check_consistency(self) -> None:
        from pac_model.pantograph_file import load_pantograph_file

        from .catenary.catenary_file import load_catenary

        load_catenary(self.catenary)  # a bad file: one line (its key, value, what is allowed)
        if self.pantograph:
            chain = load_pantograph_file(self.pantograph)
            if plant_kind(self.catenary_model).paper_pantograph_shape:  # eq. (5), else one line
                chain.table1("pantograph")
        spacings = self.pantographs
        if spacings[0] != 0.0 or any(b <= a for a, b in zip(spacings, spacings[1:], strict=False)):
            raise ParameterError(
                "pantographs", spacings, "distances behind the first pantograph: 0 first, then increasing"
            )
        if len(spacings) > 1 and not plant_kind(self.catenary_model).several_pantographs:
            raise ParameterError(
                "pantographs",
                spacings,
                f"one pantograph (0) on the {self.catenary_model} line; several need catenary_model "
                + " or ".join(several_pantograph_models()),
            )
        if self.controlled_pantograph >= len(spacings):
            raise ParameterError(
                "controlled_pantograph",
                self.controlled_pantograph,
                f"an index into pantographs, an integer in [0, {len(spacings) - 1}]",
            )
        if self.all_pantographs_active and len(spacings) != 2:
            raise ParameterError(
                "all_pantographs_active", True, "false, or true with two pantographs (a pair loop)"
            )
        if len(spacings) > 1:
            load_pantograph_file(self.passive_pantograph, "passive_pantograph")
