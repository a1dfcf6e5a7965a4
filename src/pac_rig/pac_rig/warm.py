"""``python -m pac_rig.warm``: compile every core function once, into numba's on-disk cache.

``scripts/setup.sh`` runs it after each build (``NUMBA_CACHE_DIR`` is set by ``env.sh`` to
``build/numba_cache``), so that no node, tool or test process compiles at start.  It
drives the classes the way the nodes, the offline simulator, replay and re-estimation do
(same argument types, hence the same cached specialisations) and the batch kernel, then
prints how many functions were compiled or loaded.  ``--check`` exits 1 if anything had
to be compiled (i.e. the cache was missing or stale): the test of a warm cache.
"""

from __future__ import annotations

import argparse
import importlib
import sys
import time
from typing import Any

import numpy as np
from numba.core.registry import CPUDispatcher

#: Modules holding compiled functions.
MODULES = (
    "pac_common.integrate",
    "pac_common.smallmat",
    "pac_model.model",
    "pac_plant.plant",
    "pac_plant.hardware.sensors",
    "pac_plant.hardware.actuator_steps",
    "pac_plant.hardware.actuator_dispatch",
    "pac_plant.hardware.actuators",
    "pac_observer.observer_dispatch",
    "pac_plant.plant_kernels",
    "pac_plant.plant_dispatch",
    "pac_controller.reference",
    "pac_controller.backstepping",
    "pac_controller.controller",
    "pac_controller.kernel_common",
    "pac_controller.law_dispatch",
    "pac_controller.kernels",
    "pac_plant.catenary.banded",
    "pac_plant.catenary.newmark",
    "pac_plant.catenary.step",
    "pac_plant.catenary.packing",
    "pac_rig.loop",
    "pac_rig.batch",
)


def compiled_modules() -> tuple[str, ...]:
    """:data:`MODULES` and the kernel modules of the registries' compiled laws, observers and plants."""
    from pac_controller.laws import LAWS
    from pac_observer.observers import OBSERVERS
    from pac_plant.plants import PLANTS

    kernels = sorted(
        {e.kernel for e in LAWS.values() if e.kernel}
        | {e.kernel for e in OBSERVERS.values() if e.kernel}
        | {e.kernel for e in PLANTS.values() if e.kernel}
    )
    return MODULES + tuple(name for name in kernels if name not in MODULES)


def compiled_functions() -> dict[str, CPUDispatcher]:
    """Every numba dispatcher defined in :func:`compiled_modules`, by qualified name."""
    found = {}
    for name in compiled_modules():
        module = importlib.import_module(name)
        for attr, value in vars(module).items():
            if isinstance(value, CPUDispatcher) and value.py_func.__module__ == name:
                found[f"{name}.{attr}"] = value
    return found


def exercise() -> None:
    """Call the cores with the argument types production code uses (nodes, simulate, replay, batch)."""
    from pac_controller.backstepping import BacksteppingController
    from pac_rig.batch import batchable, run_batch
    from pac_rig.closed_loop import build_cores, run, run_cores
    from pac_rig.simulate import scenario_from_flat

    short = {"duration": 0.005}
    variants: list[dict[str, Any]] = [
        {},
        {"shape": "square", "contact_model": "unilateral", "noise_std": (1e-6, 1e-6), "quantisation": 1e-7},
        {"shape": "step", "law": "passive", "command_delay_ticks": 0},
        {"law": "pid"},
        {"law": "lqr"},
        {"law": "backstepping_known"},
        {"catenary_model": "fe"},
        {"law": "line_adaptive", "observer": "contact_force"},
        # a train's suite: the plant's sensor step on its records (the compiled loop's is inside it)
        {"sensors": "train_load_cell", "roof_motion": "german_low"},
    ]
    scenarios = [scenario_from_flat({**short, **v}) for v in variants]
    for s in scenarios:
        for _ in run(s):
            pass
        for _ in run_cores(s, *build_cores(s)):  # the core objects tick by tick (the nodes' calls)
            pass
    run_batch([s for s in scenarios if batchable(s)])
    # What the nodes do besides the loop: a gap bridged, a fallback, a reset, the plant's helpers.
    plant, observer, controller = build_cores(scenarios[0])
    observer.update(0, (0.0, 0.0), 0.0)
    observer.update(3, (1e-3, 2e-3), 10.0)
    observer.reset()
    controller.fallback(1)
    controller.compute(2, np.zeros(4), np.array([np.nan, 0.0, 0.0]))
    if not isinstance(controller.law, BacksteppingController):
        raise TypeError(f"the default law is {controller.name}, not backstepping: warm its helpers too")
    controller.law.stiffness_hat_derivatives(0.0, np.array([4000.0, 0.0, 0.0]))
    plant.derivative(0.0, np.zeros(4), 1.0)
    plant.measurement()
    plant.truth()
    controller.reference.steps_before(1.0)


def cache_counts(functions: dict[str, CPUDispatcher]) -> tuple[int, int]:
    """(specialisations loaded from the cache, specialisations compiled) so far in this process."""
    hits = sum(sum(f.stats.cache_hits.values()) for f in functions.values())
    misses = sum(sum(f.stats.cache_misses.values()) for f in functions.values())
    return hits, misses


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="warm", description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="exit 1 if anything was compiled")
    args = parser.parse_args(argv)
    start = time.perf_counter()
    functions = compiled_functions()
    exercise()
    hits, misses = cache_counts(functions)
    print(
        f"warm: {len(functions)} compiled functions, {hits} specialisations loaded from the cache, "
        f"{misses} compiled, {time.perf_counter() - start:.1f} s"
    )
    if args.check and misses:
        compiled = sorted(n for n, f in functions.items() if f.stats.cache_misses)
        print(f"warm: compiled (cache missing or stale): {', '.join(compiled)}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
