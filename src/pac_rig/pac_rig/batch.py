"""Many offline scenarios in one process: the closed loop of :func:`pac_rig.closed_loop.run`, compiled.

:func:`run_batch` packs N scenarios into arrays (one row per scenario) and runs the
whole tick loop of each in compiled code, groups of scenarios in parallel threads (the compiled loop
releases the GIL).  The loop calls the same compiled core functions as the classes
``Plant``, ``AdaptiveObserver`` and ``BacksteppingController`` do, in the same order,
so every trace equals the one ``closed_loop.run`` gives, bit for bit
(``tests/test_batch.py``).  Every law with a compiled kernel (all five); a scenario the
compiled loop has no form for (the FE line: :func:`batchable`) is refused with a ValueError.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np
from numba import njit

from pac_controller.kernels import LAW_CODES

from .closed_loop import Scenario, build_cores, divergence_reason
from .loop import MAX_DELAY, TICK, CompiledLoop, compile_loop, loop_tick

#: Per-tick traces, rows of ``BatchResult.traces[name]`` (NaN after a divergence): fields of loop.TICK.
TRACES = ("contact_force", "force_reference", "u", "stiffness", "stiffness_hat", "z1")


@njit(cache=True, nogil=True, error_model="numpy")
def _run_rows(rows, ticks, pp, ps, oc, os, cp, cs, noise, out, result_tick, result_code, result_value):
    """The scenarios ``rows`` (one thread), each tick by :func:`pac_rig.loop.loop_tick`, into ``out``.

    Threads rather than numba's ``parallel=True``: compiled for parallel, the same core
    functions gave results a few ulp apart from the per-tick path's (seen), which would
    break "batch == closed_loop.run bit for bit".
    """
    rec = np.zeros(1, TICK)[0]
    for i in rows:
        code, value = 0, 0.0
        reached = ticks[i]
        quiet = noise.shape[1] == 1
        for k in range(ticks[i]):
            j = 0 if quiet else k
            code, value = loop_tick(
                k, pp[i], ps[i], oc[i], os[i], cp[i], cs[i], noise[i, j, 0], noise[i, j, 1], rec
            )
            if code:
                reached = k
                break
            out[i, 0, k], out[i, 1, k], out[i, 2, k] = rec.contact_force, rec.force_reference, rec.u
            out[i, 3, k], out[i, 4, k], out[i, 5, k] = rec.stiffness, rec.stiffness_hat, rec.z[0]
        result_tick[i], result_code[i], result_value[i] = reached, code, value


@dataclass(frozen=True)
class BatchResult:
    """Traces of N runs: ``traces[name][i, k]`` is tick k of scenario i (NaN from its divergence on)."""

    traces: dict[str, np.ndarray]
    ticks: np.ndarray  # (N,) ticks run (the scenario's, or the tick it diverged at)
    diverged: list[str | None]  # the closed_loop.DivergenceError reason, None when the run finished
    wall_seconds: float
    sample_period: np.ndarray  # (N,) [s]

    @property
    def simulated_seconds(self) -> float:
        return float(np.sum(self.ticks * self.sample_period))


def pack(scenarios: Sequence[Scenario]) -> tuple:
    """The records :func:`_run_rows` takes after ``rows`` (one per scenario, from the cores' set-up)."""
    loops = []
    for i, s in enumerate(scenarios):
        loop = compile_loop(*build_cores(s), s.loop.command_delay_ticks)
        if loop is None:
            raise ValueError(
                f"scenario {i}: the compiled loop has no form for catenary_model {s.plant.catenary_model} "
                f"with law {s.controller.effective_law}"
            )
        loops.append(loop)
    ticks = np.array([s.loop.ticks for s in scenarios], dtype=np.int64)
    noisy = [s for s in scenarios if any(v > 0.0 for v in s.plant.noise_std)]
    noise = np.zeros((len(scenarios), int(ticks.max()) if noisy else 1, 2))
    for i, s in enumerate(scenarios):
        if any(v > 0.0 for v in s.plant.noise_std):
            noise[i, : s.loop.ticks] = build_cores(s)[0].noise_rows(0, s.loop.ticks)
    records = [
        np.concatenate([getattr(loop, f.name) for loop in loops]) for f in dataclasses.fields(CompiledLoop)
    ]
    return (ticks, *records, noise)


def batchable(s: Scenario) -> bool:
    """What the compiled loop runs (:func:`pac_rig.loop.compile_loop` is not None), told from the
    parameters without building the cores: the lumped line, the adaptive observer, a law with a
    kernel, the delay it holds."""
    return (
        s.plant.catenary_model == "lumped"
        and s.observer.observer == "adaptive"
        and s.controller.effective_law in LAW_CODES
        and 0 <= s.loop.command_delay_ticks <= MAX_DELAY
    )


def run_batch(scenarios: Sequence[Scenario], threads: int = 1) -> BatchResult:
    """Run every scenario offline (compiled closed loop), the scenarios shared among ``threads`` threads."""
    if not scenarios:
        raise ValueError("run_batch needs at least one scenario")
    if threads < 1:
        raise ValueError(f"threads must be >= 1, got {threads!r}")
    args = pack(scenarios)
    n = len(scenarios)
    out = np.full((n, len(TRACES), int(args[0].max())), np.nan)
    result_tick, result_code, result_value = (
        np.zeros(n, dtype=np.int64),
        np.zeros(n, dtype=np.int64),
        np.zeros(n),
    )
    # Interleaved groups: neighbouring scenarios often cost alike (e.g. a sweep row).
    groups = [np.arange(g, n, threads, dtype=np.int64) for g in range(min(threads, n))]
    start = time.perf_counter()
    with ThreadPoolExecutor(max_workers=len(groups)) as pool:
        # One tuple of arguments per group (mypy cannot check a star-argument followed by more
        # positional ones against submit's signature).
        calls = [(rows, *args, out, result_tick, result_code, result_value) for rows in groups]
        done = [pool.submit(_run_rows, *call) for call in calls]
        for future in done:
            future.result()
    wall = time.perf_counter() - start
    return BatchResult(
        traces={name: out[:, j, :] for j, name in enumerate(TRACES)},
        ticks=result_tick,
        diverged=[
            None if c == 0 else divergence_reason(int(c), float(v))
            for c, v in zip(result_code, result_value, strict=True)
        ],
        wall_seconds=wall,
        sample_period=args[1]["dt"].copy(),
    )
