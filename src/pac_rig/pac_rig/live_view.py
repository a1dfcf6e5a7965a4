"""``ros2 run pac_rig live_view``: the rig's topics, live, in Foxglove (WebSocket protocol).

Serves ``measurement``, ``plant_truth``, ``estimate``, ``command`` and ``/diagnostics``
through the foxglove-sdk WebSocket server, bound to 127.0.0.1 by default: open the Foxglove app,
*Open connection* -> *Foxglove WebSocket*, ``ws://127.0.0.1:8765``, and plot e.g.
``/plant_truth.contact_force``, ``/command.u`` and ``/estimate.stiffness_hat``.

Which clients connect: the SDK speaks the WebSocket subprotocol ``foxglove.sdk.v1`` only
(the v1 protocol under its new name, as foxglove_bridge 3.x does). Current Foxglove app
releases offer it; Lichtblick 1.21 and earlier and older Foxglove Studio offer only
``foxglove.websocket.v1`` and are refused in the handshake (HTTP 400); the SDK has no
switch for the old name. Use a client that connects to foxglove_bridge 3.x.

The channels carry the serialised CDR bytes as received, with the same ``ros2msg``
schemas the bags carry (pac_bag's type store), so nothing is deserialised here.
It stays off the loop's critical path: it subscribes a topic only while a client
watches it, best effort and keep last ``depth`` (a slow viewer loses samples instead
of holding back a publisher), and forwards at most ``rate_hz`` messages per topic and
second on average (decimation).
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass

from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.subscription import Subscription

from pac_bag.typestore import typestore
from pac_common import messages
from pac_common.node import PacNode, run_node
from pac_common.parameters import ParameterError, ParameterSet, parameter

#: The only WebSocket subprotocol foxglove-sdk 0.30 accepts (its handshake refuses others).
SUBPROTOCOL = "foxglove.sdk.v1"


@dataclass(frozen=True)
class LiveViewParameters(ParameterSet):
    host: str = parameter("127.0.0.1", "address the WebSocket server binds (0.0.0.0: every interface)")
    port: int = parameter(8765, "WebSocket port (0: any free port, logged at start)", low=0, high=65535)
    rate_hz: float = parameter(
        50.0,
        "most messages forwarded per topic and second, on average (decimation)",
        "Hz",
        low=0.0,
        high=1e6,
        low_open=True,
    )
    depth: int = parameter(
        10, "samples each subscription keeps (keep last N, best effort)", low=1, high=10000
    )
    topics: str = parameter(
        "measurement,plant_truth,estimate,command,diagnostics",
        "comma-separated topics to serve (of " + ", ".join(messages.WATCHED_TOPICS) + ")",
    )


def ros2msg_schema(typename: str) -> bytes:
    """The message definition with its dependencies, as in the bags' MCAP schemas."""
    text, _ = typestore().generate_msgdef(typename, ros_version=2)
    return text.encode()


class LiveViewNode(PacNode):
    PARAMETER_SETS = [LiveViewParameters]
    FROZEN_REASON = "fixed for a run: restart live_view"

    def __init__(self) -> None:
        super().__init__("live_view")
        params = self.parameters(LiveViewParameters)
        names = [t.strip() for t in params.topics.split(",") if t.strip()]
        if not names or any(t not in messages.WATCHED_TOPICS for t in names):
            raise ParameterError(
                "topics", params.topics, "a comma-separated subset of " + ",".join(messages.WATCHED_TOPICS)
            )
        import foxglove

        self.fox_context = foxglove.Context()
        try:
            self.server = foxglove.start_server(
                name="pac live_view", host=params.host, port=params.port, context=self.fox_context
            )
        except Exception as exc:  # noqa: BLE001 - the SDK raises its own error type for bind failures
            raise ParameterError("port", str(params.port), f"a free port on {params.host} ({exc})") from None
        self.period_ns = int(1e9 / params.rate_hz)
        self.qos = QoSProfile(
            history=HistoryPolicy.KEEP_LAST, depth=params.depth, reliability=ReliabilityPolicy.BEST_EFFORT
        )
        self.forwarded = dict.fromkeys(names, 0)
        self.channels = {}
        for topic in names:
            typename = messages.WATCHED_TOPICS[topic]
            schema = foxglove.Schema(name=typename, encoding="ros2msg", data=ros2msg_schema(typename))
            self.channels[topic] = foxglove.Channel(
                f"/{topic}", schema=schema, message_encoding="cdr", context=self.fox_context
            )
        self.subscriptions_by_topic: dict[str, Subscription] = {}
        self.create_timer(self.FOLLOW_PERIOD, self._follow_clients)
        self.url = f"ws://{params.host}:{self.server.port}"
        # One line a user (and the tests) can read the actual port from.
        print(
            f"live_view: serving {', '.join(names)} on {self.url} (Foxglove: open a WebSocket connection; "
            f"subprotocol {SUBPROTOCOL}: current Foxglove app; clients offering only foxglove.websocket.v1, "
            "e.g. Lichtblick <= 1.21, are refused)",
            file=sys.stderr,
            flush=True,
        )

    #: s: how often the ROS subscriptions are made to follow the clients' subscriptions.
    FOLLOW_PERIOD = 0.25

    def _follow_clients(self) -> None:
        """Subscribe a topic only while a client watches its channel: unwatched, the live view
        costs the loop nothing (not even a matched reader). Runs in the executor's thread."""
        for topic, channel in self.channels.items():
            watched = channel.has_sinks()
            if watched and topic not in self.subscriptions_by_topic:
                cls = self.factory.cls(messages.WATCHED_TOPICS[topic])
                self.subscriptions_by_topic[topic] = self.create_subscription(
                    cls, messages.GRAPH_NAMES[topic], self._forwarder(topic, channel), self.qos, raw=True
                )
            elif not watched and topic in self.subscriptions_by_topic:
                self.destroy_subscription(self.subscriptions_by_topic.pop(topic))

    def _forwarder(self, topic: str, channel):
        # Every node's status matters and they come about once a second: never decimated.
        period = 0 if topic == "diagnostics" else self.period_ns
        due = [0]

        def callback(data: bytes) -> None:
            now = time.time_ns()
            if now < due[0]:
                return
            # On average rate_hz even when samples arrive in bursts (a late one lets the next
            # through early); after a pause, no backlog of credit.
            due[0] = max(due[0] + period, now - period)
            channel.log(bytes(data), log_time=now)
            self.forwarded[topic] += 1

        return callback

    def health_counters(self) -> dict:
        return {
            "state": "running",
            "url": self.url,
            **{f"forwarded_{t}": n for t, n in self.forwarded.items()},
        }

    def close(self) -> None:
        super().close()
        self.server.stop()
        counts = ", ".join(f"{t}={n}" for t, n in self.forwarded.items())
        print(f"live_view: stopped ({counts} messages forwarded)", file=sys.stderr, flush=True)


def main(args: list[str] | None = None) -> int:
    return run_node("live_view", LiveViewNode, args)


if __name__ == "__main__":
    sys.exit(main())
