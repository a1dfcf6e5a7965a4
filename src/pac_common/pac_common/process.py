"""The life of a node process: check the command line, start rclpy, spin, stop cleanly.

A bad command line, params file, parameter value or ``ROS_DOMAIN_ID`` is one line on stderr
and exit status 2; SIGINT / SIGTERM are a clean shutdown with exit status 0.
"""

from __future__ import annotations

import contextlib
import faulthandler
import os
import signal
import sys
import tempfile
import threading
from collections.abc import Iterator, Sequence

from .command_line import UsageError, check_domain_id, check_ros_arguments, set_process_arguments
from .discovery import loopback_only
from .executor import make_executor
from .exit_guard import exit_after
from .node_help import node_help, print_help
from .parameters import ParameterError
from .scheduling import normal_scheduling


def run_node(program: str, node_class: type, args: list[str] | None = None) -> int:
    """Initialise rclpy, build the node, spin until shutdown; the exit status of the program.

    ``--help`` prints the usage and parameters (exit 0). ``EventsExecutor.spin()`` busy-loops
    in these rclpy wheels; a ``spin_once`` loop does not.
    """
    return run_nodes(program, [node_class], args)


def run_nodes(program: str, node_classes: Sequence[type], args: list[str] | None = None) -> int:
    """:func:`run_node` for several nodes in one process and one executor (a component container).

    The process runs until every node is ``finished`` (or a signal); each node is then closed
    in order; the status is the first non-zero one.  Parameters reach each node by name
    (``--params-file`` with one section per node): a global ``-p`` would reach all of them,
    and each refuses the names it does not declare.
    """
    argv = list(sys.argv if args is None else args)[1:]
    outside = argv[: argv.index("--ros-args")] if "--ros-args" in argv else argv
    if "--help" in outside or "-h" in outside:
        print_help("\n\n".join(node_help(program, cls) for cls in node_classes))
        return 0
    try:
        check_domain_id()
        set_process_arguments(check_ros_arguments(argv))
    except UsageError as exc:
        print(f"{program}: {exc}", file=sys.stderr)
        return 2
    loopback_only()
    # `kill -USR1 <pid>` prints every thread's traceback on stderr, the process going on: how a
    # stop that hangs shows where (the rig sends it before it kills a process that did not stop).
    faulthandler.register(signal.SIGUSR1, all_threads=True)
    # SIGINT / SIGTERM only note the stop; the loop below ends within one spin_once and the
    # teardown runs in order, in this thread: nodes closed, executor shut down, nodes destroyed,
    # the context shut down last. rclpy's own handlers (not installed: SignalHandlerOptions.NO)
    # shut the context down from their thread at once; when that fell inside the executor's
    # first registration of the nodes' entities, the EventsExecutor kept callbacks it no longer
    # tracked and aborted the process when it was destroyed (SIGABRT, "Destroying callback
    # manager with callbacks remaining", about 1 stop in 300 right after start-up). Python's
    # default handler would raise KeyboardInterrupt at whatever line runs, e.g. inside close().
    interrupted = threading.Event()
    for stop_signal in (signal.SIGINT, signal.SIGTERM):
        signal.signal(stop_signal, lambda *_: interrupted.set())
    import rclpy
    from rclpy.executors import ExternalShutdownException
    from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
    from rclpy.signals import SignalHandlerOptions

    # rcl logs its own "[ERROR] ... Failed to parse global arguments" on stderr before it raises:
    # held back while it starts, so a refusal is pac's one line; on success it is passed on.
    refusal = ""
    with _stderr_held() as held:
        try:
            rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
        except _rclpy.RCLError as exc:  # anything check_ros_arguments did not foresee
            held.pass_on = False
            refusal = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
    if refusal:
        print(f"{program}: cannot start: {refusal.split(', at /')[0]}", file=sys.stderr)
        return 2
    nodes: list = []
    executor = None
    status = 0
    try:
        try:
            for cls in node_classes:
                nodes.append(cls())
        except ParameterError as exc:
            print(f"{program}: {exc}", file=sys.stderr)
            status = 2
            return 2
        executor = make_executor()
        for node in nodes:
            executor.add_node(node)
        while rclpy.ok() and not interrupted.is_set() and not all(node.finished for node in nodes):
            executor.spin_once(timeout_sec=0.1)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except Exception as exc:  # noqa: BLE001 - report, then exit non-zero with a clean shutdown
        # The context is shut down by this function only (no signal handler of rclpy's), so an
        # error raised by a callback or by the executor is never part of a stop.
        print(f"{program}: fatal: {exc!r}", file=sys.stderr)
        status = 1
    finally:
        if nodes and status != 2:
            for node in nodes:
                if node.configured:
                    node.close()  # the node's own results (bag, counters) are final from here on
                else:  # a managed node never configured (or cleaned up): only its last status
                    node.health.final_report()
                node.health.print_stats()
                status = status or node.exit_status
            # Tearing down rclpy in these wheels was seen to hang, rarely, inside
            # destroy_node with the GIL held (a Python timer thread then never runs: the rig
            # killed such a process); everything that matters is done, so a stuck teardown ends
            # the process with its status by a C-library timer thread (exit_guard). No
            # real-time thread may starve it (normal scheduling first).
            sys.stdout.flush()
            sys.stderr.flush()
            normal_scheduling()
            faulthandler.dump_traceback_later(4.0)  # where it hung, into the log, then:
            exit_after(5.0, status)
            if executor is not None:
                executor.shutdown(timeout_sec=1.0)
        for node in nodes:
            node.destroy_node()
        rclpy.try_shutdown()
    # The process is ending, its results final: a stop that comes now (a launcher's SIGINT to a
    # node that ended on its own) has nothing left to stop. Ignored, because the interpreter's
    # finalisation resets a Python handler to the default, and the default kills: exit -2 instead
    # of the node's status.
    for stop_signal in (signal.SIGINT, signal.SIGTERM):
        signal.signal(stop_signal, signal.SIG_IGN)
    return status


class _HeldStderr:
    """What a C library wrote on stderr while it was held; ``pass_on``: copy it to stderr after."""

    pass_on = True


@contextlib.contextmanager
def _stderr_held() -> Iterator[_HeldStderr]:
    """File descriptor 2 into a temporary file for the block (C libraries write there, not to
    ``sys.stderr``); what was written is then copied to the real stderr, unless the block set
    ``pass_on`` False (a refusal that says it all in one line)."""
    sys.stderr.flush()
    saved = os.dup(2)
    held = _HeldStderr()
    with tempfile.TemporaryFile() as capture:
        os.dup2(capture.fileno(), 2)
        try:
            yield held
        finally:
            sys.stderr.flush()
            os.dup2(saved, 2)
            os.close(saved)
            capture.seek(0)
            text = capture.read()
            if held.pass_on and text:
                sys.stderr.write(text.decode(errors="replace"))
                sys.stderr.flush()
