"""``ros2 run pac_rig recorder``: record the pac topics to a rosbag2 directory (MCAP).

By default (``ros2 bag record -a``) every pac topic and ``/diagnostics`` (every node's
health, ``diagnostic_msgs/DiagnosticArray``) are recorded.

Subscriptions take the serialised (CDR) messages as they arrive and put them on
a queue with the receive time; a writer thread does all file I/O, so nothing
slow sits on the subscription callbacks' path.  The bag's log time is the wall
time of reception (the header stamps carry the simulated time).  SIGINT/SIGTERM,
``stop_after_tick`` or ``idle_timeout`` close the bag cleanly (summary written).
Messages DDS reports lost on a subscription (never received) are counted per topic, in
``/diagnostics`` (ERROR: the bag is incomplete) and in the bag's ``lost_messages``, which
every bag reader reports.
"""

from __future__ import annotations

import math
import shutil
import sys
import threading
import time
from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path

from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.qos import DurabilityPolicy, ReliabilityPolicy

from pac_bag.mcap_writer import COMPRESSIONS
from pac_bag.metadata import LOST_MESSAGES
from pac_bag.qos import qos_dict
from pac_bag.writer import DEFAULT_COMPRESSION, BagWriter
from pac_common import messages
from pac_common.lifecycle import LifecycleOptions
from pac_common.node import RECORD_QOS, RECORD_QOS_COMPATIBLE, PacNode, run_node
from pac_common.parameters import (
    ParameterError,
    ParameterSet,
    RunEndOptions,
    SchedulingOptions,
    check_new_directory,
    parameter,
)

RECORDABLE, GRAPH_NAMES = messages.WATCHED_TOPICS, messages.GRAPH_NAMES
#: Topics a run may not have (``pantograph_truth``: only an FE line with several pantographs): the
#: recorder looks for their publishers until OPTIONAL_GRACE [s] after every other topic had its own.
OPTIONAL_TOPICS = {"pantograph_truth"}
OPTIONAL_GRACE = 2.0


@dataclass(frozen=True)
class RecorderParameters(ParameterSet):
    bag_path: str = parameter("", "output bag directory (must not exist); empty: bags/run_<date>_<time>")
    topics: str = parameter(
        ",".join(RECORDABLE), "comma-separated topics to record (of " + ", ".join(RECORDABLE) + ")"
    )
    stop_after_tick: int = parameter(
        -1,
        "close the bag and exit once this tick has been recorded on every topic (-1: never)",
        low=-1,
    )
    compression: str = parameter(
        DEFAULT_COMPRESSION, "MCAP chunk compression of the bag", choices=COMPRESSIONS
    )
    idle_timeout: float = parameter(
        0.0,
        "close the bag and exit after this long without any message, once recording began (0: never)",
        "s",
        low=0.0,
        high=3600.0,
    )
    min_free_disk_mb: float = parameter(
        50.0,
        "/diagnostics reports ERROR while the bag's file system has less free space than this",
        "MB",
        low=0.0,
        runtime=True,
    )


class RecorderNode(PacNode):
    PARAMETER_SETS = [RecorderParameters, RunEndOptions, SchedulingOptions, LifecycleOptions]
    FROZEN_REASON = "fixed for a recording: start another recorder"
    HEALTH = "recorder"

    def __init__(self) -> None:
        super().__init__("recorder")

    def configure(self) -> None:
        params = self.parameters(RecorderParameters)
        path = Path(params.bag_path or f"bags/run_{datetime.now():%Y%m%d_%H%M%S}")
        check_new_directory("bag_path", path)
        names = [t.strip() for t in params.topics.split(",") if t.strip()]
        if not names or any(t not in RECORDABLE for t in names):
            raise ParameterError(
                "topics", params.topics, "a comma-separated subset of " + ",".join(RECORDABLE)
            )
        topics = {t: RECORDABLE[t] for t in names}
        self.params: RecorderParameters = params
        # Topics enter the bag when their publishers are seen, with the QoS they offer (ros2 bag).
        try:
            self.bag = BagWriter(
                path, {"source": "live", "label": path.name}, topics={}, compression=params.compression
            )
        except OSError as exc:
            raise ParameterError(
                "bag_path", str(path), f"a writable new directory ({exc.strerror or exc})"
            ) from None
        self.path = path
        # deque.append/popleft are atomic: the callbacks append, the writer thread drains in
        # batches every WRITE_PERIOD, which costs far fewer wake-ups than a queue per message.
        self.pending: deque = deque()
        self.lost: dict[str, int] = {}  # messages DDS reports lost per topic (never recorded)
        self.stopping = threading.Event()
        self.failed = False
        self.failure = ""
        # The recorded tick of each loop topic (run end, stop_after_tick); /diagnostics has none.
        self.last_tick = {t: -1 for t in topics if t in messages.TOPICS}
        self.last_message_wall: float | None = None
        self.factory = messages.RclpyFactory()
        self.unsubscribed = dict(topics)
        self.all_but_optional_at = 0.0  # when every topic but the optional ones had publishers
        self.subscribe_timer = self.create_timer(0.01, self._subscribe_when_published)
        self.writer = threading.Thread(target=self._write_loop, name="bag-writer", daemon=True)
        self.writer.start()
        self.follow_run()
        if params.idle_timeout > 0:
            self.idle_check_period = min(0.1, params.idle_timeout / 2)
            self.last_idle_check = time.monotonic()
            self.create_timer(self.idle_check_period, self._check_idle)
        self.get_logger().info(f"recording {', '.join(topics)} to {path}")

    WRITE_PERIOD = 0.01  # s: how often the writer thread drains the callbacks' queue
    FLUSH_PERIOD = 0.5  # s: how often a chunk is closed and flushed (bounds the loss on SIGKILL)

    def _subscribe_when_published(self) -> None:
        """Subscribe each topic once it has publishers, with the QoS they offer (as ros2 bag does):
        reliable and transient-local when all of them offer it (pac's own nodes: nothing sent
        before the match completes is lost), else best effort, so that any publisher is recorded."""
        if not self.active:
            return  # a managed recorder subscribes once activated: the loop waits for it
        for topic, typename in list(self.unsubscribed.items()):
            offered = self.get_publishers_info_by_topic(GRAPH_NAMES[topic])
            if not offered:
                continue
            durable = all(
                info.qos_profile.reliability == ReliabilityPolicy.RELIABLE
                and info.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL
                for info in offered
            )
            qos = RECORD_QOS if durable else RECORD_QOS_COMPATIBLE
            # The writer thread owns the file: the topic enters the bag through the queue, ahead
            # of any of its messages.
            self.pending.append((topic, None, (typename, [qos_dict(info.qos_profile) for info in offered])))
            self.create_subscription(
                self.factory.cls(typename),
                GRAPH_NAMES[topic],
                self._callback(topic),
                qos,
                raw=True,
                event_callbacks=SubscriptionEventCallbacks(message_lost=self._lost_callback(topic)),
            )
            del self.unsubscribed[topic]
            if topic in OPTIONAL_TOPICS:  # published: its last tick counts for the run's end too
                self.last_tick[topic] = -1
            self.get_logger().info(
                f"recording '{topic}' ({len(offered)} publisher(s), "
                f"{'reliable, transient local' if durable else 'best effort'})"
            )
        if set(self.unsubscribed) <= OPTIONAL_TOPICS:
            # A plant publishes its optional topic with the others or not at all: stop looking soon.
            now = time.monotonic()
            self.all_but_optional_at = self.all_but_optional_at or now
            if not self.unsubscribed or now - self.all_but_optional_at > OPTIONAL_GRACE:
                self.destroy_timer(self.subscribe_timer)

    def _callback(self, topic: str):
        append = self.pending.append

        def callback(data: bytes) -> None:
            if self.active:  # a deactivated (managed) recorder drops what arrives
                append((topic, data, time.time_ns()))

        return callback

    def _lost_callback(self, topic: str):
        """Count what DDS says this subscription lost for good: with reliable, keep-last publishers
        a sample is lost when the publisher dropped it from its history (PUBLISH_QOS keeps 1000,
        one second of the loop) before the recorder had it, e.g. a transport drop whose repair
        came after that (the writer's heartbeat, Fast DDS's default every 3 s) on a loaded host.
        The count goes into /diagnostics and the bag (``lost_messages``): never silent."""

        def lost(info) -> None:
            self.lost[topic] = self.lost.get(topic, 0) + int(info.total_count_change)

        return lost

    def _write_loop(self) -> None:
        last_flush = time.monotonic()
        while not self.stopping.wait(self.WRITE_PERIOD):
            self._drain()
            if time.monotonic() - last_flush >= self.FLUSH_PERIOD and not self.failed:
                self._guard(self.bag.flush)
                last_flush = time.monotonic()
        self._drain()

    def _guard(self, action) -> bool:
        """Run a file operation; a full disk (or any OS error) stops recording with one clear line."""
        try:
            action()
            return True
        except OSError as exc:
            self.failure = str(exc.strerror or exc)
            self.failed = True
            self.exit_status = 1
            self.finished = True
            self.pending.clear()
            print(
                f"recorder: recording stopped: {exc.strerror or exc} ({self.path}); "
                f"what was written before stays readable (ros2 run pac_analysis recover {self.path})",
                file=sys.stderr,
                flush=True,
            )
            return False

    def _drain(self) -> None:
        pending = self.pending
        wrote = False
        while pending and not self.failed:
            topic, data, stamp = pending.popleft()
            if data is None:  # a new topic: (type, offered QoS profiles)
                if not self._guard(lambda t=topic, st=stamp: self.bag.add_topic(t, *st)):
                    return
                continue
            if not self._guard(lambda t=topic, d=data, st=stamp: self.bag.write_raw(t, d, st)):
                return
            wrote = True
            if topic in self.last_tick:
                self.last_tick[topic] = max(self.last_tick[topic], messages.cdr_tick(data))
        if wrote:
            self.last_message_wall = time.monotonic()
            stop_tick = self.params.stop_after_tick
            if stop_tick >= 0 and self.recorded_tick() >= stop_tick:
                self.finished = True
            self._check_run_recorded()

    def _check_run_recorded(self) -> None:
        """stop_after_run: the ended run's last tick is in the bag on every recorded loop topic."""
        last = self.run_last_tick
        if last is not None and self.recorded_tick() >= last:
            self.handled_tick(last)

    def recorded_tick(self) -> float:
        """The last tick recorded on every loop topic (infinite when none is recorded)."""
        return min(self.last_tick.values(), default=math.inf)

    def on_run_end(self) -> None:
        self._check_run_recorded()

    def _check_idle(self) -> None:
        now = time.monotonic()
        late = now - self.last_idle_check > 2 * self.idle_check_period + 0.05
        self.last_idle_check = now
        if late and self.last_message_wall is not None:
            # This check ran late: the recorder itself was kept off the CPU (a loop at a higher
            # SCHED_FIFO priority on a small host), and the executor runs this timer before the
            # subscriptions that hold the backlog. The silence was ours, not the publishers':
            # closing now would cut a running run's bag (seen on one core, 5 s starved).
            self.last_message_wall = now
            return
        last = self.last_message_wall
        if last is not None and now - last > self.params.idle_timeout:
            self.get_logger().info(f"no message for {self.params.idle_timeout:g} s: closing")
            self.finished = True

    def apply_parameters(self, changed: Mapping[type[ParameterSet], ParameterSet]) -> None:
        self.params = self.changed_or(changed, RecorderParameters, self.params)

    def health_counters(self) -> dict:
        try:
            bag_bytes = sum(f.stat().st_size for f in self.path.iterdir())
            free_mb = shutil.disk_usage(self.path).free / 1e6
        except OSError:
            bag_bytes, free_mb = -1, math.nan
        try:
            counts = self.bag.counts
        except RuntimeError:  # the writer thread added a topic just now: next report
            counts = {}
        if self.failed:
            state = "failed"
        else:
            state = "ended" if self.run_ended else "recording"
        return {
            "state": state,
            "bag_path": str(self.path),
            "messages": sum(counts.values()),
            **{f"messages_{topic}": n for topic, n in counts.items()},
            "bag_bytes": bag_bytes,
            "free_disk_mb": round(free_mb, 3),
            "min_free_disk_mb": self.params.min_free_disk_mb,
            "queued": len(self.pending),
            "lost_messages": sum(self.lost.values()),
            **{f"lost_{topic}": n for topic, n in self.lost.items()},
            "failed": self.failed,
            "failure": self.failure,
        }

    def unconfigure(self) -> None:
        """Lifecycle cleanup: the bag is closed and complete, as at the end of a run."""
        self.close()

    def close(self) -> None:
        """Drain the queue, write the summary and metadata: the bag is complete and indexed."""
        super().close()
        self.stopping.set()
        self.writer.join()
        if self.failed:
            return
        lost = dict(self.lost)
        self.bag.set_metadata(LOST_MESSAGES, lost)
        if not self._guard(self.bag.close):
            return
        counts = ", ".join(f"{t}={n}" for t, n in self.bag.counts.items())
        print(f"recorder: closed {self.path} ({counts})", file=sys.stderr, flush=True)
        if any(lost.values()):
            print(
                f"recorder: {self.path}: messages lost before they reached the recorder: "
                + ", ".join(f"{t}={n}" for t, n in lost.items() if n),
                file=sys.stderr,
                flush=True,
            )


def main(args: list[str] | None = None) -> int:
    return run_node("recorder", RecorderNode, args)


if __name__ == "__main__":
    sys.exit(main())
