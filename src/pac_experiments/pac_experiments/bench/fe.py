"""The FE line's cost per 1 kHz step, by part: the compiled step, and its right-hand side and solve beside
the kernels they replaced.

``python -m pac_experiments.bench.fe`` prints a table; ``fe_tick_figures()`` returns the
figures (``make bench`` calls it). CPU time (``time.process_time``) per step, median and
minimum over batches, on the 10-span moving window the rig runs (``FEPlant``: paper's
pantograph, 300 km/h, warmed past the first span so that every contact column is cached).
Timing is measured, never asserted: the machine is shared; the load average is printed.

Also measured, for the physical limit of one step on this machine (docs/numerics.md):
the memory bandwidth (numpy copy, in L2 and in DRAM), the latency of one dependent
multiply-add (the banded solve is a chain of them) and the bytes one step touches.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from collections.abc import Callable

import numba
import numpy as np

from pac_common import markdown
from pac_model.parameters import PantographParameters, TrackParameters
from pac_plant.catenary.banded import KD, band_chol_solve, chunk_solve
from pac_plant.catenary.newmark import newmark_rhs, newmark_rhs_mass, newmark_update
from pac_plant.catenary.step import StepConstants, StepState, fe_step
from pac_plant.fe_plant import FEPlant
from pac_plant.parameters import PlantOptions

SPEED_KMH = 300.0
FORCE = 157.3  # N, EN 50367 target at 300 km/h
COARSE_ELEMENT = 0.75  # m


def per_call(fn: Callable[[], object], calls: int, batches: int) -> tuple[float, float]:
    """(median, minimum) CPU microseconds per call over ``batches`` batches of ``calls`` calls."""
    times = []
    for _ in range(batches):
        start = time.process_time()
        for _ in range(calls):
            fn()
        times.append(1e6 * (time.process_time() - start) / calls)
    return statistics.median(times), min(times)


def warm_plant(element_size: float = 0.5) -> FEPlant:
    plant = FEPlant(
        PantographParameters(),
        TrackParameters(speed_kmh=SPEED_KMH),
        None,
        PlantOptions(catenary_model="fe", fe_element_size=element_size),
        1e-3,
    )
    for _ in range(1500):  # past the first window shift: the contact columns are all cached
        plant.advance(FORCE)
    return plant


@numba.njit(cache=True)
def _steps(c: StepConstants, s: StepState, force: float, n: int) -> None:
    for _ in range(n):
        fe_step(c, s, force)


@numba.njit(cache=True)
def _fma_chain(x: float, a: float, b: float, n: int) -> float:
    for _ in range(n):
        x = x * a + b
    return x


def copy_bandwidth(nbytes: int, repeats: int) -> float:
    """GB/s of a numpy copy of ``nbytes`` (read + write counted), best of ``repeats``."""
    src = np.ones(nbytes // 8)
    dst = np.zeros_like(src)
    np.copyto(dst, src)  # pages touched before timing
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        np.copyto(dst, src)
        best = min(best, time.perf_counter() - start)
    return 2 * nbytes / best / 1e9


def fe_tick_figures(steps: int = 2000, batches: int = 10) -> dict[str, float]:
    """Microseconds per step by part, old and new path, and the machine figures (see module doc)."""
    calls = max(1, steps // batches)
    plant = warm_plant()
    sim = plant.sim
    c, s = sim.constants, sim.state
    out: dict[str, float] = {"load_average_1min": os.getloadavg()[0], "n_dof": float(sim.line.n_dof)}

    def tick() -> None:
        plant.advance(FORCE)
        plant.measurement()
        plant.truth()

    def put(name: str, fn: Callable[[], object]) -> None:
        out[f"{name}_us"], out[f"{name}_us_min"] = per_call(fn, calls, batches)

    put("fe_plant_tick", tick)
    # The coarser mesh the convergence study allows (docs/numerics.md): 0.75 m elements.
    coarse = warm_plant(COARSE_ELEMENT)
    out["n_dof_coarse"] = float(coarse.sim.line.n_dof)

    def tick_coarse() -> None:
        coarse.advance(FORCE)
        coarse.measurement()
        coarse.truth()

    put("fe_plant_tick_coarse", tick_coarse)
    put("step_new", lambda: sim.step(FORCE))
    # What a compiled caller (a compiled closed loop, the batch) pays: fe_step in a compiled loop.
    _steps(c, s, FORCE, 1)
    out["step_compiled_us"], out["step_compiled_us_min"] = per_call(
        lambda: _steps(c, s, FORCE, calls), 1, batches
    )
    out["step_compiled_us"] /= calls
    out["step_compiled_us_min"] /= calls
    # Parts of the new step, on copies of the state (the solve on a fresh right-hand side).
    d, v, a = s.d.copy(), s.v.copy(), s.a.copy()
    rhs, y, dt = np.empty_like(d), np.empty_like(d), sim.dt
    x1, x2 = np.zeros(len(d) + 2 * KD), np.zeros(len(d) + 2 * KD)
    newmark_rhs_mass(c.m_pad, d, v, a, dt, sim.alpha, sim.beta, x1, x2[: len(d)], rhs)
    work = np.zeros_like(s.chunk_work)

    def solve() -> None:
        y[:] = rhs
        chunk_solve(c.chunk_factors, c.chunk_starts, c.chunk_bounds, y, work, x2[: len(d)])

    def solve_old() -> None:
        y[:] = rhs
        band_chol_solve(c.chol, y)

    tail = x2[: len(d)]
    put("rhs_new", lambda: newmark_rhs_mass(c.m_pad, d, v, a, dt, sim.alpha, sim.beta, x1, tail, y))
    m_band, k_band, _ = sim.bands
    put("rhs_old", lambda: newmark_rhs(m_band, k_band, d, v, a, dt, sim.alpha, sim.beta, x1, x2, y))
    put("solve_new", solve)
    put("solve_old", solve_old)
    put("copy_vector", lambda: np.copyto(y, rhs))
    put("update", lambda: newmark_update(d, v, a, rhs, dt))
    readings = np.zeros(5)
    put("call_and_readings", lambda: sim.advance(FORCE, 0, plant.flexibility, readings))
    put("measurement_truth", lambda: (plant.measurement(), plant.truth()))
    out["fe_plant_realtime_factor"] = 1e3 / out["fe_plant_tick_us"]
    out["step_compiled_realtime_factor"] = 1e3 / out["step_compiled_us"]
    # The rest of the compiled step: contact column, pantograph, active set, Woodbury, patches.
    for suffix in ("_us", "_us_min"):
        parts = out["rhs_new" + suffix] + out["solve_new" + suffix] + out["update" + suffix]
        out["rest" + suffix] = out["step_compiled" + suffix] - parts
    # Machine: one dependent multiply-add (the solve's chain), memory bandwidth.
    _fma_chain(1.0, 0.5, 0.25, 10)
    n_chain = 20_000_000
    start = time.process_time()
    _fma_chain(1.0, 0.999999, 1e-9, n_chain)
    out["dependent_multiply_add_ns"] = 1e9 * (time.process_time() - start) / n_chain
    out["copy_bandwidth_l2_gb_s"] = copy_bandwidth(256 * 1024, 200)
    out["copy_bandwidth_dram_gb_s"] = copy_bandwidth(256 * 1024 * 1024, 5)
    # Bytes one step streams through the L2 cache: the M band, the solve's factors (both sweeps),
    # the vectors: d v a, tail, rhs (right-hand side); rhs in, the lane-major scratch written and
    # read twice (1.3 n each), tail, solution (solve); d v a and the solution in, d v a out (update).
    n = len(d)
    matrices = c.m_pad.nbytes + 2 * c.chunk_factors.nbytes
    vectors = 8 * n * (5 + 1 + 4 * 1.3 + 2 + 7)
    out["bytes_per_step"] = float(matrices + vectors)
    out["stream_bound_us"] = out["bytes_per_step"] / (out["copy_bandwidth_l2_gb_s"] * 1e3)
    # The solve's dependency chain: per row one dependent fused multiply-add (LDL^T, the newest
    # term last), both sweeps; the eight chunks run side by side in the lanes of one vector.
    chain_rows = c.chunk_factors.shape[0] - 2 * KD
    out["solve_chain_bound_us"] = 2 * chain_rows * out["dependent_multiply_add_ns"] / 1e3
    return out


def table(f: dict[str, float]) -> str:
    def m(name: str) -> str:  # median (minimum)
        return f"{f[name + '_us']:.1f} ({f[name + '_us_min']:.1f})"

    rows = [
        ("FEPlant tick (advance + measurement + truth), new", m("fe_plant_tick"), ""),
        ("  x real time (1 kHz)", f"{f['fe_plant_realtime_factor']:.1f}", "goal >= 25"),
        (
            f"FEPlant tick, fe_element_size {COARSE_ELEMENT} m ({int(f['n_dof_coarse'])} DOFs)",
            m("fe_plant_tick_coarse"),
            f"{1e3 / f['fe_plant_tick_coarse_us']:.1f}x real time",
        ),
        ("step (compiled fe_step, called from Python)", m("step_new"), ""),
        (
            "**step in a compiled loop** (what a compiled caller pays)",
            f"**{m('step_compiled')}**",
            f"**{f['step_compiled_realtime_factor']:.0f}x real time** (goal >= 25)",
        ),
        ("  right-hand side: old (M, K) / new (M)", f"{m('rhs_old')} / {m('rhs_new')}", ""),
        ("  banded solve: old / new", f"{m('solve_old')} / {m('solve_new')}", "incl. a copy"),
        ("  Newmark update", m("update"), ""),
        ("  the rest (contact, pantograph, active set, Woodbury)", m("rest"), "step - parts"),
        ("  call from Python + contact readings", m("call_and_readings"), ""),
        ("FEPlant measurement() + truth() (Python)", m("measurement_truth"), ""),
        ("solve: dependency-chain bound", f"{f['solve_chain_bound_us']:.1f}", ""),
        ("step: bytes streamed / L2 copy bandwidth", f"{f['stream_bound_us']:.1f}", "memory bound"),
        ("dependent multiply-add [ns]", f"{f['dependent_multiply_add_ns']:.2f}", ""),
        (
            "copy bandwidth L2 / DRAM [GB/s]",
            f"{f['copy_bandwidth_l2_gb_s']:.0f} / {f['copy_bandwidth_dram_gb_s']:.0f}",
            "",
        ),
        ("bytes streamed per step [kB]", f"{f['bytes_per_step'] / 1e3:.0f}", ""),
    ]
    lines = [
        f"FE line, 10-span window, {int(f['n_dof'])} DOFs, 300 km/h; CPU us per step, median (minimum) "
        f"of the batches (load average {f['load_average_1min']:.1f})",
        "",
        markdown.table(["what", "us", "note"], rows, ["l", "r", "l"]),
    ]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="bench_fe", description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=2000, help="steps timed per figure (default 2000)")
    args = parser.parse_args(argv)
    if args.steps < 10:
        print(f"bench_fe: --steps {args.steps} is below 10", file=sys.stderr)
        return 2
    print(table(fe_tick_figures(args.steps)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
