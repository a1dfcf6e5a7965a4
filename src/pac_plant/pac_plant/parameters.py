"""How the plant is simulated: options that are not part of the paper's model."""

from __future__ import annotations

from dataclasses import dataclass

from pac_common.parameters import ParameterSet, parameter


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
        "catenary: 'lumped' k(t) = k0 (1 + alpha cos(omega t - beta)) of eq. (7); 'fe' the "
        "finite-element line of the file 'catenary' (docs/catenary.md; endless moving window; "
        "ignores k0/alpha/beta/span_length and contact_model: its contact is always unilateral)",
        choices=("lumped", "fe"),
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

    def check_consistency(self) -> None:
        from .catenary.catenary_file import load_catenary

        load_catenary(self.catenary)  # a bad file: one line (its key, value, what is allowed)
        if self.pantograph:
            from pac_model.pantograph_file import load_pantograph_file

            chain = load_pantograph_file(self.pantograph)
            if self.catenary_model == "lumped":  # eq. (5): the paper's 2-DOF shape, else one line
                chain.table1("pantograph")
