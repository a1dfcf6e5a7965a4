"""Many offline scenarios in one process: the closed loop of :func:`pac_rig.closed_loop.run`, compiled.

:func:`run_batch` packs N scenarios into arrays (one row per scenario) and runs the
whole tick loop of each in compiled code, groups of scenarios in parallel threads (the compiled loop
releases the GIL).  The loop calls the same compiled core functions as the classes
``Plant``, ``AdaptiveObserver`` and ``BacksteppingController`` do, in the same order,
so every trace equals the one ``closed_loop.run`` gives, bit for bit
(``tests/test_batch.py``).  Every compiled law (pac's kernel laws by the cached loop; a law
module's or a user's compiled file by its own loop, :func:`_run_law_block`), every line, every
observer; a scenario the compiled loop has no form for (:func:`batchable`: a law at Python speed,
too much delay) is refused with a ValueError.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np
from numba import njit

from pac_common import divergence
from pac_controller.laws import law_entry
from pac_observer.choice import observer_entry

from .closed_loop import BLOCK, Scenario, build_cores
from .loop import MAX_DELAY, TICK, CompiledLoop, compile_loop, loop_tick

#: Per-tick traces, rows of ``BatchResult.traces[name]`` (NaN after a divergence): fields of loop.TICK.
TRACES = (
    "contact_force", "force_reference", "u", "stiffness", "stiffness_hat", "z1", "contact_force_hat",
    "contact_uplift", "contact_position", "u_applied", "saturated",
)  # fmt: skip


@njit(cache=True, nogil=True, error_model="numpy")
def _run_one(
    ticks, pp, ps, fe_args, oc, os, bank, cp, cs, table, memory, noise, out, tick_record
) -> tuple[int, int, float]:
    """One scenario, tick by tick by :func:`pac_rig.loop.loop_tick`, its TRACES into ``out``
    (len(TRACES) x ticks); (ticks reached, divergence code, value). ``tick_record``: one
    ``loop.TICK`` row, each tick's record (the caller's array: see below).

    The record array comes from the caller because a numba record does not keep its array alive:
    ``np.zeros(1, TICK)[0]`` in here freed the array at once and every tick then wrote into freed
    memory that any allocation, of this thread or another, could be handed (docs/numerics.md,
    "The batch's threads").

    One thread runs one scenario at a time (``run_batch``).  Threads rather than numba's
    ``parallel=True``: compiled for parallel, the same core functions gave results a few ulp
    apart from the per-tick path's (seen), which would break "batch == closed_loop.run bit for bit".
    """
    rec = tick_record[0]
    quiet = noise.shape[0] == 1
    p, s, o, q, c, d = pp[0], ps[0], oc[0], os[0], cp[0], cs[0]
    for k in range(ticks):
        j = 0 if quiet else k
        code, value = loop_tick(k, p, s, fe_args, o, q, bank, c, d, table, memory, noise[j], rec)
        if code:
            return k, code, value
        out[0, k], out[1, k], out[2, k] = rec.contact_force, rec.force_reference, rec.u
        out[3, k], out[4, k], out[5, k] = rec.stiffness, rec.stiffness_hat, rec.z[0]
        out[6, k], out[7, k] = rec.contact_force_hat, rec.contact_uplift
        out[8, k], out[9, k], out[10, k] = rec.contact_position, rec.u_applied, rec.saturated
    return ticks, 0, 0.0


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


def _run_law_block(
    loop: CompiledLoop, ticks: int, noise: np.ndarray, out: np.ndarray
) -> tuple[int, int, float]:
    """:func:`_run_one` for a law of the file protocol (a law module or a user's compiled file),
    whose loop is its own closure (``CompiledLoop.block``, not in the disk cache, so not callable
    from the cached ``_run_one``): ticks of BLOCK at a time into a TICK array, its TRACES copied out.
    The same compiled ticks as ``closed_loop.run``'s, so the same numbers."""
    block = np.empty(max(1, min(ticks, BLOCK)), TICK)
    for k0 in range(0, ticks, block.size):
        k1 = min(ticks, k0 + block.size)
        reached, code, value = loop.run(k0, k1, noise if noise.shape[0] == 1 else noise[k0:k1], block)
        done = block[: reached - k0]
        for j, name in enumerate(TRACES):
            out[j, k0:reached] = done["z"][:, 0] if name == "z1" else done[name]
        if code:
            return reached, code, value
    return ticks, 0, 0.0


def prepare(i: int, s: Scenario) -> tuple[CompiledLoop, np.ndarray]:
    """The compiled loop of scenario ``i`` and its sensor noise (one row per tick, or one zero row)."""
    cores = build_cores(s)
    loop = compile_loop(*cores, s.loop.command_delay_ticks)
    if loop is None:
        raise ValueError(
            f"scenario {i}: the compiled loop has no form for catenary_model {s.plant.catenary_model}, "
            f"observer {s.observer.observer}, law {s.controller.effective_law}, "
            f"command_delay_ticks {s.loop.command_delay_ticks}"
        )
    noise = cores[0].noise_rows(0, s.loop.ticks)
    if loop.block is not None:  # compiled here, in the building thread: never in two threads at once
        loop.run(0, 0, noise[:1], np.empty(1, TICK))
    return loop, noise


class BatchFault(RuntimeError):
    """A run's trace broke what the safety chain guarantees: memory the run used was overwritten."""


def actuator_violation(u: np.ndarray, s: Scenario) -> tuple[int, str] | None:
    """(tick, what) of the first command ``u`` (one run's trace, NaN after a divergence) that
    the safety chain cannot give: outside [u_min, u_max], or a step from the previous tick's larger
    than ``slew_rate_max`` x period (``kernels.limit_command``, which every command passes,
    the fallback's too). None when every tick keeps both: any correct run does.

    A run whose memory was overwritten while it ran (docs/numerics.md, "The batch's threads") shows
    it here at once: its records turn to garbage and the first garbage command breaks one of the
    two (seen: -500 N, then 4e-98 N one tick later)."""
    c = s.controller
    ticks = int(np.argmax(np.isnan(u))) if np.isnan(u).any() else u.size
    u = u[:ticks]
    # Relative slack for rounding: the limits are applied to doubles as given.
    tol = 1e-9 * max(abs(c.u_min), abs(c.u_max), 1.0)
    outside = np.flatnonzero((u < c.u_min - tol) | (u > c.u_max + tol))
    step = c.slew_rate_max * s.loop.sample_period
    jumps = np.flatnonzero(np.abs(np.diff(u)) > step * (1.0 + 1e-9) + tol) + 1
    first_outside = int(outside[0]) if outside.size else u.size
    first_jump = int(jumps[0]) if jumps.size else u.size
    if first_outside == first_jump == u.size:
        return None
    if first_outside <= first_jump:
        return first_outside, f"u = {u[first_outside]:.6g} N outside [{c.u_min:g}, {c.u_max:g}] N"
    k = first_jump
    return k, f"u stepped {u[k] - u[k - 1]:.6g} N in one tick (the slew limit allows {step:g} N)"


def batchable(s: Scenario) -> bool:
    """What the compiled loop runs (:func:`pac_rig.loop.compile_loop` is not None), told from the
    parameters without building the cores: every line, observer, law and sensor suite; the delay
    it holds."""
    return (
        law_entry(s.controller.effective_law).compiled
        and observer_entry(s.observer.observer).kernel is not None
        and 0 <= s.loop.command_delay_ticks <= MAX_DELAY
    )


def run_batch(scenarios: Sequence[Scenario], threads: int = 1) -> BatchResult:
    """Run every scenario offline (compiled closed loop), the scenarios shared among ``threads`` threads."""
    if not scenarios:
        raise ValueError("run_batch needs at least one scenario")
    if threads < 1:
        raise ValueError(f"threads must be >= 1, got {threads!r}")
    n = len(scenarios)
    ticks = np.array([s.loop.ticks for s in scenarios], dtype=np.int64)
    out = np.full((n, len(TRACES), int(ticks.max())), np.nan)
    result_tick, result_code, result_value = (
        np.zeros(n, dtype=np.int64),
        np.zeros(n, dtype=np.int64),
        np.zeros(n),
    )

    def run_loop(i: int, loop: CompiledLoop, noise: np.ndarray) -> None:
        if loop.block is not None:
            result_tick[i], result_code[i], result_value[i] = _run_law_block(
                loop, int(ticks[i]), noise, out[i]
            )
            return
        record = np.zeros(1, TICK)
        result_tick[i], result_code[i], result_value[i] = _run_one(
            int(ticks[i]), *loop.args(), noise, out[i], record
        )

    start = time.perf_counter()
    # Zero ticks of the first scenario here first: numba compiles (or loads) the loop in this thread,
    # not in two threads at once on their first call (which crashed).
    first, noise = prepare(0, scenarios[0])
    _run_one(0, *first.args(), noise, out[0], np.zeros(1, TICK))
    # Groups: the cores of a group are built here, one after the other and while no loop runs; then
    # the group's compiled ticks run in the threads. Built in the threads, pid / lqr FE runs were
    # corrupted (|u| of 1e153 .. 1e259 N); the cause was the per-tick record pointing into freed
    # memory (now the caller's array, above), but building here costs little and keeps the
    # threads to compiled code only (docs/numerics.md). A group bounds the memory held (an FE
    # loop is ~8 MB).
    group = 4 * threads
    with ThreadPoolExecutor(max_workers=min(threads, n)) as pool:
        for g0 in range(0, n, group):
            built = [(i, *prepare(i, scenarios[i])) for i in range(g0, min(n, g0 + group))]
            for future in [pool.submit(run_loop, *b) for b in built]:
                future.result()
    wall = time.perf_counter() - start
    for i, s in enumerate(scenarios):
        broken = actuator_violation(out[i, TRACES.index("u"), : result_tick[i]], s)
        if broken is not None:
            raise BatchFault(
                f"scenario {i}: at tick {broken[0]} {broken[1]}: the safety chain cannot give that, so "
                "memory this run used was overwritten while it ran; no result of this batch is "
                'trusted (rerun it; docs/numerics.md, "the batch\'s threads")'
            )
    return BatchResult(
        traces={name: out[:, j, :] for j, name in enumerate(TRACES)},
        ticks=result_tick,
        diverged=[
            None if c == 0 else divergence.reason(int(c), float(v))
            for c, v in zip(result_code, result_value, strict=True)
        ],
        wall_seconds=wall,
        sample_period=np.array([s.loop.sample_period for s in scenarios]),
    )
