"""Run the rig as four real processes (``ros2 run``) without launch files.

Used by ``make demo``, ``make bench`` and the integration tests.  Every process
gets the caller's ROS_DOMAIN_ID and loopback-only discovery; only processes this
object started are signalled, by PID; :meth:`Rig.stop` (also on ``__exit__``)
sends SIGINT, then SIGKILL after a grace period, so nothing outlives a failed test.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pac_observer.parameters import ObserverParameters

from . import composition, scenario_file
from .configs import parameter_sets
from .nodes import LOOP_NODES, NODES

#: SCHED_FIFO priorities the rig asks for by default: the loop above the recorder (a starved
#: recorder catches up from the publishers' reliable history; a starved loop misses its ticks),
#: both above every normal process. Refused (no root or CAP_SYS_NICE): one warning line per
#: node, which then runs with normal scheduling. ``priorities={}`` asks for nothing; lock step
#: (a simulation, no deadlines) asks for nothing by default.
REALTIME_PRIORITIES = {"plant": 60, "observer": 60, "controller": 60, "recorder": 50}


def ros_args(params: dict[str, Any]) -> list[str]:
    out = ["--ros-args"]
    for name, value in params.items():
        if isinstance(value, bool):
            text = "true" if value else "false"
        elif isinstance(value, list | tuple):
            text = "[" + ", ".join(repr(float(v)) for v in value) + "]"
        else:
            text = str(value)
        out += ["-p", f"{name}:={text}"]
    return out


def params_file_sections(params: dict[str, dict[str, Any]]) -> dict[str, dict[str, dict[str, Any]]]:
    """A ROS 2 parameter file's sections of each node's values (``params``: by role): one section
    per node, named as the node is (its executable's name; the relays keep it)."""

    def values(role: str) -> dict[str, Any]:
        return {k: list(v) if isinstance(v, tuple) else v for k, v in params[role].items()}

    return {NODES[role].executable: {"ros__parameters": values(role)} for role in params}


def node_env(domain_id: int | None = None) -> dict[str, str]:
    env = dict(os.environ)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    if domain_id is not None:
        env["ROS_DOMAIN_ID"] = str(domain_id)
    env.setdefault("PYTHONUNBUFFERED", "1")
    return env


@dataclass
class Process:
    name: str
    popen: subprocess.Popen
    log_path: Path
    cpu_seconds: float | None = None
    wall_seconds: float | None = None
    started: float = field(default_factory=time.monotonic)

    @property
    def returncode(self) -> int | None:
        return self.popen.returncode

    def poll(self) -> int | None:
        if self.popen.returncode is None:
            try:
                pid, status, usage = os.wait4(self.popen.pid, os.WNOHANG)
            except ChildProcessError:
                return self.popen.poll()
            if pid:
                self.popen.returncode = os.waitstatus_to_exitcode(status)
                self.cpu_seconds = usage.ru_utime + usage.ru_stime
                self.wall_seconds = time.monotonic() - self.started
        return self.popen.returncode

    def wait(self, timeout: float) -> int | None:
        deadline = time.monotonic() + timeout
        while self.poll() is None and time.monotonic() < deadline:
            time.sleep(0.02)
        return self.popen.returncode

    def log(self) -> str:
        try:
            return self.log_path.read_text(errors="replace")
        except OSError:
            return ""


def node_parameters(
    params: dict[str, dict[str, Any]] | None,
    *,
    duration: float,
    timing_mode: str = "realtime",
    record: bool = True,
    relay: bool = False,
    priorities: dict[str, int] | None = None,
) -> dict[str, dict[str, Any]]:
    """Each node's parameters for a run (the recorder's without its bag path), composed from
    ``params`` (per node, and ``"all"``: the rig's flat names, a ``scenario`` included) as
    :class:`Rig` runs them: the scenario file's values under the user's own, each value to the
    nodes that have it; then what the parts derive from each other: the observer the controller's
    law needs where none was named (and the form of F_hat a fixed-gain law reads from it), the static
    force of an actuator as hardware (the run's reference); and a refusal (CompositionError, one
    line) of a law on an observer that does not give what it needs. The arguments are
    :class:`Rig`'s."""
    if priorities is None:
        # Lock step is a simulation that runs flat out: at SCHED_FIFO it would starve the
        # recorder (seen: two lock-step rigs at once lost the last third of a bag) and has no
        # deadline to meet anyway.
        priorities = REALTIME_PRIORITIES if timing_mode == "realtime" else {}
    # A scenario file's values go to the nodes that have them, under the user's own.
    shared, _ = scenario_file.expand({"wait_for_recorder": record, **(params or {}).get("all", {})})

    def common(name: str) -> dict[str, Any]:
        # "all" goes to every loop node that has the parameter (an unknown name is refused).
        names = {spec.name for cls in parameter_sets(name) for spec in cls.specs()}
        return {k: v for k, v in shared.items() if k in names}

    loop_names = {s.name for n in LOOP_NODES for c in parameter_sets(n) for s in c.specs()}
    unknown = sorted(set(shared) - loop_names)
    if unknown:
        raise ValueError(f"unknown parameter '{unknown[0]}' in params['all']: no loop node has it")

    # The run ends by itself: the plant announces its end, the others stop once they have
    # handled (recorded) its last tick; idle_timeout guards a recorder that never hears it.
    nodes: dict[str, dict[str, Any]] = {
        "recorder": {"stop_after_run": True, "idle_timeout": 5.0},
        "observer": {**common("observer"), "stop_after_run": True},
        "controller": {**common("controller"), "stop_after_run": True},
        "plant": {**common("plant"), "timing_mode": timing_mode, "duration": duration},
    }
    for name, priority in priorities.items():
        if "realtime_priority" not in shared:
            nodes[name]["realtime_priority"] = priority
    if timing_mode == "lockstep":
        # The plant waits for every command: a wall-clock watchdog has nothing to guard
        # and would perturb an exact run when a sample is re-sent.
        nodes["controller"]["watchdog_ticks"] = 0
    for name, extra in (params or {}).items():
        if name != "all":
            nodes[name].update(extra)
    # What the parts derive from each other.
    static_force = composition.actuator_static_force({**nodes["controller"], **nodes["plant"]})
    if static_force is not None:
        nodes["plant"]["actuator_static_force"] = static_force
    law = nodes["controller"].get("law")
    if law is None or relay:
        return nodes
    # The plant's parts too: its line (a whole line's map), its sensors (the observer they
    # allow), its actuator (the law's design for it).
    derived, _ = composition.derive(
        {"law": law}, {**nodes["plant"], **nodes["observer"], **nodes["controller"]}
    )
    for name in ("observer", "controller"):  # each derived value to the node that has it
        names = {spec.name for cls in parameter_sets(name) for spec in cls.specs()}
        nodes[name].update({k: v for k, v in derived.items() if k != "law" and k in names})
    observer = nodes["observer"].get("observer", ObserverParameters().observer)
    composition.check_pair(
        str(law),
        str(observer),
        nodes["controller"].get("force_estimate"),
        str(nodes["plant"].get("sensors", "ground")),
    )
    return nodes


class Rig:
    """The three loop nodes and the recorder, as separate processes."""

    def __init__(
        self,
        bag_path: Path | str,
        *,
        duration: float,
        timing_mode: str = "realtime",
        params: dict[str, dict[str, Any]] | None = None,
        domain_id: int | None = None,
        log_dir: Path | str | None = None,
        record: bool = True,
        relay: bool = False,
        priorities: dict[str, int] | None = None,
        prefix: str | None = None,
        composed: bool = False,
    ) -> None:
        """``relay``: the floor rig (cores that do no work); ``priorities``: SCHED_FIFO priority per
        node (default: :data:`REALTIME_PRIORITIES` in real time, none in lock step; ``params``
        override it); ``prefix``: a command that wraps every node (``ros2 run --prefix``, e.g.
        ``setpriv --bounding-set=-sys_nice``);
        ``composed``: the three loop nodes in one process ``loop`` (``ros2 run pac_rig composed``)."""
        self.composed = composed
        self.relay = relay
        self.bag_path = Path(bag_path)
        self.duration = duration
        self.domain_id = domain_id
        self.log_dir = Path(log_dir) if log_dir else self.bag_path.parent / f"{self.bag_path.name}_logs"
        self.record = record
        self.prefix = prefix
        self.params = node_parameters(
            params,
            duration=duration,
            timing_mode=timing_mode,
            record=record,
            relay=relay,
            priorities=priorities,
        )
        self.params["recorder"] = {"bag_path": str(self.bag_path), **self.params["recorder"]}
        self.processes: dict[str, Process] = {}

    def composed_command(self) -> list[str]:
        """``composed`` with a params file holding one section per node (by node name)."""
        import yaml

        path = self.log_dir / "composed_params.yaml"
        sections = params_file_sections({name: self.params[name] for name in LOOP_NODES})
        path.write_text(yaml.safe_dump(sections))
        return [
            "pac_rig",
            "composed",
            *(["--relay"] if self.relay else []),
            "--ros-args",
            "--params-file",
            str(path),
        ]

    def start_node(self, name: str, life: int = 1) -> Process:
        """Start one node (``loop``: the composed loop); ``life`` > 1 names the log of a restart."""
        self.log_dir.mkdir(parents=True, exist_ok=True)
        log_path = self.log_dir / (f"{name}.log" if life == 1 else f"{name}.{life}.log")
        prefix = ["--prefix", self.prefix] if self.prefix else []
        if name == "loop":
            command = ["ros2", "run", *prefix, *self.composed_command()]
        elif self.prefix:
            node = NODES[name]
            exe = node.relay_executable if self.relay else node.executable
            command = ["ros2", "run", *prefix, node.package, exe, *ros_args(self.params[name])]
        else:
            # The node's module run by this interpreter: what `ros2 run` execs in the end, without
            # the stand-in's own interpreter and the entry script's metadata lookup (≈ 0.1 s of CPU
            # of each node's start-up, docs/numerics.md).
            module = NODES[name].module(self.relay)
            command = [sys.executable, "-m", module, *ros_args(self.params[name])]
        with open(log_path, "wb") as log:
            popen = subprocess.Popen(
                command,
                stdout=log,
                stderr=subprocess.STDOUT,
                stdin=subprocess.DEVNULL,
                env=node_env(self.domain_id),
            )
        proc = self.processes[name] = Process(name, popen, log_path)
        return proc

    def start(self) -> Rig:
        names = ["loop"] if self.composed else list(LOOP_NODES)
        if self.record:
            names.insert(0, "recorder")
        for name in names:
            self.start_node(name)
        return self

    def wait_finished(self, timeout: float) -> None:
        """Wait for the run to end by itself (every node stops after the plant's last tick)."""
        deadline = time.monotonic() + timeout
        for name in ("plant", "loop", "recorder", "observer", "controller"):
            proc = self.processes.get(name)
            if proc is not None:
                proc.wait(max(0.0, deadline - time.monotonic()))
                if proc.returncode is None:
                    raise TimeoutError(f"{name} did not finish within {timeout:g} s:\n{proc.log()[-2000:]}")
        self.stop()

    def signal(self, name: str, sig: int = signal.SIGINT) -> None:
        proc = self.processes[name]
        if proc.poll() is None:
            os.kill(proc.popen.pid, sig)

    def stop(self, grace: float = 10.0, recorder_grace: float = 30.0) -> dict[str, int | None]:
        """SIGINT the loop's processes, then the recorder (it records to the end and then closes
        its bag with nothing more arriving); SIGKILL what still runs after ``grace`` (the
        recorder: ``recorder_grace``) seconds, after SIGUSR1 made it print every thread's
        traceback into its log (``pac_common.process``), whose end goes to stderr. Exit codes."""
        loop = [name for name in self.processes if name != "recorder"]
        last = [name for name in self.processes if name == "recorder"]
        for names, wait in ((loop, grace), (last, recorder_grace)):
            for name in names:
                self.signal(name, signal.SIGINT)
            deadline = time.monotonic() + wait
            for name in names:
                self.processes[name].wait(max(0.0, deadline - time.monotonic()))
            for name in names:
                self._kill_stuck(self.processes[name], wait)
        return {name: proc.returncode for name, proc in self.processes.items()}

    def _kill_stuck(self, proc: Process, waited: float) -> None:
        """SIGKILL a process that did not stop after SIGINT, with the evidence of where it was."""
        if proc.poll() is not None:
            return
        os.kill(proc.popen.pid, signal.SIGUSR1)
        proc.wait(1.0)
        if proc.poll() is None:
            os.kill(proc.popen.pid, signal.SIGKILL)
            proc.wait(5.0)
        print(
            f"rig: {proc.name} (pid {proc.popen.pid}) did not stop within {waited:g} s of SIGINT: "
            f"killed; the end of its log ({proc.log_path}):\n{proc.log()[-6000:]}",
            file=sys.stderr,
            flush=True,
        )

    def kill(self, name: str) -> int | None:
        """SIGKILL one node (a crash) and reap it; its exit code."""
        proc = self.processes[name]
        if proc.poll() is None:
            os.kill(proc.popen.pid, signal.SIGKILL)
        return proc.wait(10.0)

    def restart(self, name: str) -> Process:
        lives = getattr(self, "_lives", {})
        lives[name] = lives.get(name, 1) + 1
        self._lives = lives
        return self.start_node(name, lives[name])

    def exit_codes(self) -> dict[str, int | None]:
        return {name: proc.poll() for name, proc in self.processes.items()}

    def __enter__(self) -> Rig:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()
