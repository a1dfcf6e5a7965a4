"""Parameters of the Kalman-like adaptive observer, eq. (17) and Section 6."""

from __future__ import annotations

from dataclasses import dataclass

from pac_common.parameters import ParameterSet, parameter

from .observers import OBSERVERS, observer_help

#: What each observer gives a law besides z_hat (``observer`` chooses one; the registry's, observers.py).
#: A fixed-gain law (pid, lqr) reads F_hat in the first form its observer gives
#: (pac_controller.laws.FORCE_ESTIMATE_NEEDS).
OBSERVER_GIVES: dict[str, frozenset[str]] = {name: entry.gives for name, entry in OBSERVERS.items()}


@dataclass(frozen=True)
class ObserverParameters(ParameterSet):
    """Observer selection; tuning of eq. (17) (defaults: Section 6's values, Sigma read as 100 I_2)
    and of the contact-force Kalman filter (pac_observer.contact_force, docs/laws.md)."""

    observer: str = parameter(
        "adaptive",
        observer_help(),
        choices=tuple(OBSERVER_GIVES),
        or_file=".py",
    )
    force_process_noise: float = parameter(
        2e4,
        "contact_force: intensity q_F of the random walk of F (sets F_hat's bandwidth)",
        "N/s^0.5",
        low=0.0,
        low_open=True,
        high=1e9,
    )
    position_noise: float = parameter(
        1e-5,
        "contact_force: standard deviation r of the position measurement the filter assumes",
        "m",
        low=0.0,
        low_open=True,
        high=0.1,
    )
    frame_mass_range: float = parameter(
        0.3,
        "contact_force: the filter bank covers the frame mass m2 from (1 - this) to (1 + this) times "
        "Table 1's (0: one filter on the nominal m2)",
        "",
        low=0.0,
        high=0.9,
    )
    frame_mass_step: float = parameter(
        0.025,
        "contact_force: relative step of m2 between two filters of the bank",
        "",
        low=0.001,
        high=0.9,
    )
    head_balance_window: float = parameter(
        2.0,
        "head_balance: time constant T over which F_hat's mean follows the actuator's force (the "
        "momentum balance; above 1/(2 pi T) F_hat is the head's balance)",
        "s",
        low=0.01,
        high=1000.0,
    )
    frame_mass_window: float = parameter(
        0.5,
        "contact_force: time constant of each filter's running innovation energy (the bank picks the "
        "smallest)",
        "s",
        low=0.001,
        high=100.0,
    )

    rho_z: float = parameter(
        40.0,
        "forgetting rate of S_z; must exceed 26 (two slowest real parts of A)",
        "1/s",
        low=27.0,
        high=1000.0,
    )
    rho_theta: float = parameter(
        20.0, "forgetting rate of S_theta", "1/s", low=0.0, low_open=True, high=1000.0
    )
    sigma: tuple = parameter(
        (100.0, 100.0), "diagonal of the output weight Sigma (2x2)", "1/m^2", length=2, low=0.0, low_open=True
    )
    s_z0: float = parameter(1.0, "S_z(0) = s_z0 * I_4", "", low=0.0, low_open=True)
    s_theta0: float = parameter(1.0, "S_theta(0) = s_theta0 * I_3", "(m/N)^2", low=0.0, low_open=True)
    s_theta_floor: float = parameter(
        1e-16,
        "lower bound on S_theta's eigenvalues (guards against wind-up without excitation)",
        "(m/N)^2",
        low=0.0,
        low_open=True,
        high=1.0,
    )
    theta_hat0: tuple = parameter(
        (3000.0, 0.0, 0.0),
        "initial estimate of theta = (k0, k0 a cos b, k0 a sin b)",
        "N/m",
        length=3,
        low=-1e6,
        high=1e6,
    )
    z_hat0: tuple = parameter(
        (0.0, 0.0, 0.0, 0.0),
        "initial state estimate (z1, z2, z1', z2')",
        "m, m/s",
        length=4,
        low=-10.0,
        high=10.0,
    )
