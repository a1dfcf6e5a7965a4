"""Offline closed-loop simulation to a rosbag2/MCAP bag: ``ros2 run pac_rig simulate``."""

from __future__ import annotations

import argparse
import gc
import shutil
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from pac_bag.mcap_writer import COMPRESSIONS
from pac_bag.writer import DEFAULT_COMPRESSION, BagWriter
from pac_common import messages
from pac_common.parameters import ParameterError, check_new_directory
from pac_plant.fe_plant import several_pantographs
from pac_plant.plants import plant_kind

from . import composition, scenario_file
from .cli import OverrideError, add_override_arguments, overrides_from_args, without_ros_args
from .closed_loop import (
    BLOCK,
    Cores,
    DivergenceError,
    Scenario,
    TickRecord,
    build_cores,
    computed_ahead,
    pantograph_truths,
    run_blocks,
    run_cores,
    tick_records,
)
from .loop import compile_loop
from .progress import progress
from .scenario import from_flat, scenario_sets, scenario_to_flat


def scenario_from_flat(values: dict[str, Any], base: Scenario | None = None) -> Scenario:
    """A scenario with ``values`` (flat parameter names) over ``base``; unknown names are errors.
    A ``scenario`` file's values come in where ``values`` gives none (``scenario_file.expand``)."""
    values, _ = scenario_file.expand(values)
    return from_flat(values, base)


@dataclass(frozen=True)
class RunResult:
    bag_path: Path
    ticks: int
    diverged: str | None  # reason, when the run stopped at divergence
    wall_seconds: float
    simulated_seconds: float
    interrupted: bool = False  # Ctrl-C: the bag holds the ticks simulated until then


def plant_line(scenario: Scenario) -> tuple[str, float]:
    """(catenary_model, span length) of the line the plant simulates, as run_status announces it."""
    model = scenario.plant.catenary_model
    if plant_kind(model).line_from_file:
        from pac_plant.catenary.catenary_file import load_catenary

        return model, load_catenary(scenario.plant.catenary).data.span
    return model, scenario.track.span_length


#: Ticks collected before they are serialised and written at once (bounds the memory of long runs).
WRITE_BLOCK = 10_000


def tick_fields(rec: TickRecord, scenario: Scenario) -> dict[str, dict[str, Any]]:
    """Each topic's field dictionary of one tick, as the plant, observer and controller nodes
    build them (``pantograph_truth`` too where the record has every pantograph's truth)."""
    k = rec.measurement.tick
    stamp = messages.tick_stamp_ns(k, scenario.loop.rate_hz)
    applied = max(-1, k - 1 - scenario.loop.command_delay_ticks)
    fields = {
        "measurement": messages.measurement_fields(rec.measurement, stamp),
        "plant_truth": messages.truth_fields(rec.truth, stamp, applied_command_tick=applied),
        "estimate": messages.estimate_fields(
            rec.estimate, stamp, actuator_force=rec.measurement.actuator_force
        ),
        "command": messages.command_fields(rec.command, stamp),
    }
    if rec.pantographs:
        fields["pantograph_truth"] = pantograph_truth_fields(rec.pantographs, scenario, k, stamp)
    return fields


def pantograph_truth_fields(truths: Any, scenario: Scenario, tick: int, stamp_ns: int) -> dict[str, Any]:
    """``pantograph_truth`` of one tick: the plant node's message (its spacing: ``pantographs``)."""
    return messages.pantograph_truth_fields(truths, scenario.plant.pantographs, tick, stamp_ns)


def write_ticks(bag: BagWriter, rows: dict[str, list[dict[str, Any]]], stamps: list[int]) -> None:
    """Write collected ticks (per topic, the field dictionaries of each tick) in one go."""
    if stamps:
        times = np.array(stamps, dtype=np.int64)
        for topic, block in rows.items():
            bag.write_rows(topic, block, times)


def simulate_to_bag(
    scenario: Scenario,
    bag_path: Path | str,
    label: str = "",
    compression: str = DEFAULT_COMPRESSION,
    show_progress: bool = False,
    on_record: Callable[[TickRecord], None] | None = None,
    stop_requested: Callable[[], bool] | None = None,
    compiled: bool = True,
    cores: Cores | None = None,
) -> RunResult:
    """Run ``scenario`` offline and record the pac topics; log time = simulated time.

    Each tick's field dictionaries are the nodes' own (pac_common.messages); they are
    collected per topic and written in blocks through the vectorised CDR path.
    ``show_progress``: a tick progress bar on stderr when it is a terminal. ``on_record``
    sees every tick's record too (e.g. to compute measures without reading the bag).
    ``stop_requested`` (asked after every tick, or every block of ticks on the compiled path):
    stop there, and close the bag with what was simulated (``RunResult.interrupted``).
    ``compiled=False``: the core objects tick by tick and one field dictionary per message, the
    path before the loop was compiled (the bench compares the two; the bags are the same).
    ``cores``: the scenario's plant, observer and controller (``build_cores``) where the caller
    built them already and has not run them (a whole line's set-up is seconds), else built here."""
    rate = scenario.loop.rate_hz
    start = time.perf_counter()
    ticks = 0
    diverged = None
    interrupted = False
    model, span = plant_line(scenario)
    topics = list(messages.LOOP_TOPICS)
    rows: dict[str, list[dict[str, Any]]] = {topic: [] for topic in topics}
    stamps: list[int] = []
    with BagWriter(
        bag_path,
        {"source": "offline", "label": label, "parameters": scenario_to_flat(scenario)},
        compression=compression,
    ) as bag:

        def write_run_status(bag: BagWriter, tick: int, state: int) -> None:
            """The run's start and end, as the plant node announces them."""
            stamp = messages.tick_stamp_ns(tick, rate)
            fields = messages.run_status_fields(tick, state, scenario.loop.duration, stamp, model, span)
            bag.write("run_status", fields, stamp)

        write_run_status(bag, 0, messages.RUN_RUNNING)
        plant, observer, controller = build_cores(scenario) if cores is None else cores
        several = several_pantographs(plant) is not None
        if several:  # every pantograph's truth, as the plant node publishes it then
            topics.append("pantograph_truth")
            rows["pantograph_truth"] = []
            bag.add_topic("pantograph_truth", messages.PANTOGRAPH_TRUTH)
        delay = scenario.loop.command_delay_ticks
        loop = compile_loop(plant, observer, controller, delay) if compiled else None
        try:
            if loop is not None:  # compiled: whole blocks of ticks, written as columns
                blocks: Iterable[np.ndarray] = computed_ahead(run_blocks(scenario, plant, loop))
                if show_progress:
                    blocks = progress(blocks, -(-scenario.loop.ticks // BLOCK), label or "simulate", "block")
                controlled = loop.controlled()
                for block in blocks:
                    times = messages.tick_stamp_ns(1, rate) * block["tick"]
                    for topic, columns in messages.tick_columns(block, rate, delay).items():
                        bag.write_many(topic, columns, times)
                    if several:
                        pantographs = [
                            pantograph_truth_fields(truths, scenario, int(k), int(stamp))
                            for truths, k, stamp in zip(
                                pantograph_truths(block, controlled), block["tick"], times, strict=True
                            )
                        ]
                        bag.write_rows("pantograph_truth", pantographs, times)
                    bag.flush()
                    ticks += block.size
                    if on_record is not None:
                        for rec in tick_records(block, controlled):
                            on_record(rec)
                    if stop_requested is not None and stop_requested():
                        interrupted = True
                        break
                records: Iterable[TickRecord] = iter(())
            else:
                records = run_cores(scenario, plant, observer, controller)
            if show_progress:
                records = progress(records, scenario.loop.ticks, label or "simulate", "tick")
            for rec in records:
                for topic, fields in tick_fields(rec, scenario).items():
                    rows[topic].append(fields)
                stamps.append(messages.tick_stamp_ns(rec.measurement.tick, rate))
                ticks += 1
                if on_record is not None:
                    on_record(rec)
                if len(stamps) == WRITE_BLOCK:
                    write_ticks(bag, rows, stamps)
                    bag.flush()
                    rows = {topic: [] for topic in topics}
                    stamps = []
                if stop_requested is not None and stop_requested():
                    interrupted = True
                    break
        except DivergenceError as exc:
            diverged = str(exc)
            bag.set_metadata("diverged", {"tick": exc.tick, "reason": exc.reason})
        except KeyboardInterrupt:  # a caller without stop_requested: keep what was simulated
            interrupted = True
        if interrupted:
            bag.set_metadata("interrupted", {"ticks": ticks})
        write_ticks(bag, rows, stamps)
        write_run_status(bag, max(ticks - 1, 0), messages.RUN_ENDED)
    wall = time.perf_counter() - start
    return RunResult(Path(bag_path), ticks, diverged, wall, ticks / rate, interrupted)


def node_only(values: dict[str, Any]) -> list[str]:
    """Names in ``values`` that a pac node has but a scenario does not (start-up, scheduling, ...):
    a node's `ros2 param dump` holds them; offline they mean nothing."""
    from pac_common.command_line import pac_parameter_names

    scenario = set(scenario_to_flat(Scenario()))
    nodes = pac_parameter_names()
    return sorted(n for n in values if n not in scenario and n in nodes)


def main(argv: list[str] | None = None) -> int:
    """The ``simulate`` command (its help: ``--help``); the exit status."""
    # The imports' objects (numba's alone are a few hundred thousand) live as long as the process:
    # left out of the collector's full passes, which visited them all twice a run (~0.05 s). Thawed
    # on the way out, for a caller in the same process (a test) whose objects were frozen too.
    gc.freeze()
    try:
        return _main(argv)
    finally:
        gc.unfreeze()


def _main(argv: list[str] | None) -> int:
    parser = argparse.ArgumentParser(
        prog="simulate",
        description=__doc__,
        epilog="Parameters as for the nodes: -p NAME:=VALUE, --params-file FILE (a node's "
        "`ros2 param dump` too), optionally after --ros-args. Ctrl-C stops the run and closes the "
        "bag with what was simulated (exit 130); a diverged run exits 1. The finite-element line: "
        "-p catenary_model:=fe -p catenary:=FILE (or a preset's name: config/catenaries/); the "
        "catenary file's format is documented in docs/catenary.md, 'The catenary file'. The "
        "pantograph: -p pantograph:=FILE (or a preset's name: config/pantographs/) for the plant, "
        "-p nominal_pantograph:=FILE for the observer and controller; the pantograph file's format "
        "is documented in docs/catenary.md, 'The pantograph file'. A whole scenario: -p "
        "scenario:=FILE (or a preset's name: config/scenarios/; docs/scenarios.md). Several pantographs "
        "(-p pantographs:=[0.0,200.0]): the bag carries pantograph_truth too, every pantograph each "
        "tick, as the plant node publishes it (docs/catenary.md, 'Several pantographs').",
    )
    parser.add_argument("bag", type=Path, nargs="?", help="output bag directory (must not exist)")
    add_override_arguments(parser)
    parser.add_argument("--list", action="store_true", help="list every parameter and exit")
    args = parser.parse_args(without_ros_args(list(sys.argv[1:] if argv is None else argv)))
    if args.list:
        for pset in scenario_sets(Scenario()).values():
            for spec in pset.specs():
                print(f"{spec.name:22s} {spec.default!s:22s} {spec.allowed():40s} {spec.description}")
        presets = "|".join(scenario_file.PRESETS.names()) + "|PATH"
        about = "the run's parts from a scenario file (docs/scenarios.md); your values win"
        print(f"{'scenario':22s} {scenario_file.DEFAULT:22s} {presets:40s} {about}")
        allowed = "|".join(COMPRESSIONS)
        print(f"{'compression':22s} {DEFAULT_COMPRESSION:22s} {allowed:40s} MCAP chunk compression")
        return 0
    if args.bag is None:
        parser.error("the bag directory is required")
    try:
        check_new_directory("bag", args.bag)
        values = overrides_from_args(args)
        # simulate's own parameter before the nodes' are dropped: the recorder node has one of
        # the same name, and simulate's was dropped with them (every bag zstd).
        compression = values.pop("compression", DEFAULT_COMPRESSION)
        if compression not in COMPRESSIONS:
            raise ParameterError("compression", compression, "one of " + ", ".join(COMPRESSIONS))
        ignored = node_only(values)
        if ignored:
            print(f"simulate: ignoring the nodes' own parameters: {', '.join(ignored)}", file=sys.stderr)
            values = {k: v for k, v in values.items() if k not in ignored}
        scenario = scenario_from_flat(values)  # every value valid before anything is derived
        derived, notes = composition.derive(values)
        for note in notes:
            print(f"simulate: {note}", file=sys.stderr)
        if derived != values:
            values, scenario = derived, scenario_from_flat(derived)
        cores = build_cores(scenario)  # parts that do not fit, or a law design the parameters do not allow
        gc.freeze()  # (as in main) the line's and the loaded compiled code's objects too
    except (OverrideError, ParameterError) as exc:
        print(f"simulate: {exc}", file=sys.stderr)
        return 2
    if scenario.controller.mode == "passive":
        print("simulate: parameter 'mode' is deprecated: use law:=passive", file=sys.stderr)
    if scenario.loop.duration <= 0.0:
        print("simulate: invalid parameter 'duration' = 0.0: allowed (0, 86400] s offline", file=sys.stderr)
        return 2
    model, span = plant_line(scenario)
    if abs(span - scenario.track.span_length) > 1e-9 * span:
        print(
            f"simulate: warning: the plant runs the {model} line with {span:g} m spans but observer and "
            f"controller assume span_length {scenario.track.span_length:g} m (set -p span_length:={span:g})",
            file=sys.stderr,
        )
    # Ctrl-C asks the loop to stop after the current tick (a KeyboardInterrupt raised inside the
    # compiled cores surfaced as a SystemError traceback); the bag is then closed as usual.
    requested = threading.Event()
    previous = signal.signal(signal.SIGINT, lambda *_: requested.set())
    try:
        result = simulate_to_bag(
            scenario,
            args.bag,
            label=args.bag.name,
            compression=compression,
            show_progress=True,
            stop_requested=requested.is_set,
            cores=cores,
        )
    except OSError as exc:  # e.g. the disk filled up or the folder vanished mid-run
        # The bag is cut short where the write failed: removed, so no truncated bag is taken for
        # a run (the folder did not exist before: check_new_directory).
        shutil.rmtree(args.bag, ignore_errors=True)
        print(
            f"simulate: cannot write {args.bag}: {exc.strerror or exc}; the incomplete bag was removed",
            file=sys.stderr,
        )
        return 1
    finally:
        signal.signal(signal.SIGINT, previous)
    speed = result.simulated_seconds / max(result.wall_seconds, 1e-9)
    print(
        f"wrote {result.bag_path}: {result.ticks} ticks, {result.simulated_seconds:g} s simulated "
        f"in {result.wall_seconds:.2f} s ({speed:.1f}x real time)"
    )
    if result.interrupted:
        print(
            f"simulate: interrupted (Ctrl-C) after {result.ticks} of {scenario.loop.ticks} ticks: "
            f"the bag holds what was simulated",
            file=sys.stderr,
        )
        return 130
    if result.diverged:
        print(f"simulate: run stopped: {result.diverged}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
