"""The observers ``observer`` chooses: one registry line each, a module imported only when chosen.

An entry says what the observer gives a law besides z_hat (the composition rules read it: a law
that needs theta_hat is refused on an observer without it), its core class (the node's and the
Python loop's, ``"module:Class"``) and the module of its compiled update, which the compiled
loop calls through ``observer_dispatch``, generated from this registry
(``observer_dispatch_source``). That update is

    ``<name>_update(k, t, oc, os, bank, y1, y2, u_applied, head_acceleration)``
    -> (status, stiffness_hat, contact_force_hat)

at tick k on the records ``OBSERVER_CONSTS`` ``oc`` / ``OBSERVER_STATE`` ``os`` (k = 0: the first
sample), ``bank`` the contact-force filters' arrays (``contact_force.BANK_ARGS``; empty for the
others); status 0 or a divergence code. An observer without a compiled update (``kernel`` None)
runs in the Python loop only (``closed_loop.run_cores``).
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass


@dataclass(frozen=True)
class ObserverEntry:
    """One observer of the registry (module docstring)."""

    gives: frozenset[str]
    core: str  # "module:Class"
    #: What it is, for the ``observer`` parameter's help ("'name' description; ...").
    description: str
    kernel: str | None = None
    #: The sensor channels it reads besides the frame positions, (channel, what it is) pairs with
    #: ``pac_plant.hardware.sensors`` channel names: a run whose sensors lack one is refused.
    reads: tuple[tuple[str, str], ...] = ()
    #: The observer that stands in for this one where the run's sensors have what that one reads:
    #: a run that takes this observer from its law (none named) takes that one there.
    on_richer_sensors: str | None = None


#: The paper's observer gives the catenary parameters theta_hat, and with them F_hat = k_hat z1
#: (eqs. (6), (8)); the contact-force filter F_hat as a state of its own and no theta_hat (it
#: publishes zeros there); the head balance F_hat from the head's equation of motion.
OBSERVERS: dict[str, ObserverEntry] = {
    "adaptive": ObserverEntry(
        frozenset({"theta_hat", "contact_force_hat"}),
        "pac_observer.observer:AdaptiveObserver",
        "the paper's observer, eq. (17) (theta_hat, F_hat = k_hat z1)",
        "pac_observer.observer",
    ),
    "contact_force": ObserverEntry(
        frozenset({"contact_force_hat"}),
        "pac_observer.contact_force:ContactForceObserver",
        "a Kalman filter on the nominal pantograph with F as a random-walk state (no F = k z1; no "
        "theta_hat: for laws line_adaptive, pid, lqr (on its F_hat) or passive)",
        "pac_observer.contact_force",
        # A train's sensors: the head's own balance, not the filter that differentiates their noise
        # twice (pac_observer.head_balance, docs/laws.md).
        on_richer_sensors="head_balance",
    ),
    "head_balance": ObserverEntry(
        frozenset({"contact_force_hat"}),
        "pac_observer.head_balance:HeadBalanceObserver",
        "F from the head's equation of motion with its accelerometer (a train's sensors: "
        "sensors:=train or train_load_cell; pac_observer.head_balance)",
        "pac_observer.head_balance",
        reads=(("head_acceleration", "a head accelerometer"),),
    ),
}

#: Observer name -> its code in ``OBSERVER_CONSTS.kind`` (the registry's order, compiled ones only).
OBSERVER_CODES = {name: code for code, name in enumerate(n for n, e in OBSERVERS.items() if e.kernel)}


def observer_help() -> str:
    """The ``observer`` parameter's help: each registered observer and what it is, and the file."""
    described = "; ".join(f"'{name}' {entry.description}" for name, entry in OBSERVERS.items())
    return f"{described}; or the path of your own observer's Python file (docs/laws.md, 'Your own observer')"


def core_class(name: str) -> type:
    """The core class of observer ``name`` (its module imported now)."""
    module, _, cls = OBSERVERS[name].core.partition(":")
    found: type = getattr(importlib.import_module(module), cls)
    return found


def compiled_observer_classes() -> tuple[type, ...]:
    """The core classes of the observers with a compiled update (their modules imported now)."""
    return tuple(core_class(name) for name, entry in OBSERVERS.items() if entry.kernel)
