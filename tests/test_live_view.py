"""The live view serves the rig's topics to a Foxglove WebSocket client (Foxglove's v1 protocol)."""

import json
import re
import struct
import subprocess
import time

import numpy as np
import pytest
from conftest import ROS2, stop
from websockets.exceptions import InvalidStatus
from websockets.sync.client import connect

from pac_bag.reader import read_bag
from pac_bag.typestore import typestore
from pac_rig.launcher import node_env
from pac_rig.simulate import scenario_from_flat, simulate_to_bag

pytestmark = pytest.mark.live

TOPICS = ("measurement", "plant_truth", "estimate", "command")
SUBPROTOCOLS = ["foxglove.sdk.v1", "foxglove.websocket.v1"]
MESSAGE_DATA = 0x01  # server -> client binary opcode: subscription id u32, log time u64, payload


def wait_for_line(proc: subprocess.Popen, log, pattern: str, timeout: float) -> re.Match:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        found = re.search(pattern, log.read_text())
        if found:
            return found
        assert proc.poll() is None, log.read_text()
        time.sleep(0.05)
    raise AssertionError(f"no '{pattern}' within {timeout:g} s:\n{log.read_text()}")


def subscribed_topics(env) -> list[str]:
    """The topics live_view subscribes, from `ros2 node info` (the stand-in, by its path)."""
    info = subprocess.run(
        [ROS2, "node", "info", "/live_view"], capture_output=True, text=True, env=env, timeout=30
    )
    assert info.returncode == 0, info.stderr
    section = info.stdout.split("  Subscribers:\n")[1].split("  Publishers:")[0]
    return [line.split(":")[0].strip() for line in section.splitlines()]


def test_live_view_serves_replayed_topics_to_a_foxglove_client(tmp_path, domain_id, processes):
    bag_path = tmp_path / "offline"
    simulate_to_bag(scenario_from_flat({"duration": 2.0}), bag_path)
    bag = read_bag(bag_path)
    env = node_env(domain_id)
    log = tmp_path / "live_view.log"
    rate_hz = 20.0
    with open(log, "wb") as out:
        viewer = subprocess.Popen(
            [
                "ros2",
                "run",
                "pac_rig",
                "live_view",
                "--ros-args",
                "-p",
                "port:=0",
                "-p",
                f"rate_hz:={rate_hz}",
            ],
            stdout=out,
            stderr=subprocess.STDOUT,
            env=env,
        )
    processes.append(viewer)
    url = wait_for_line(viewer, log, r"serving .* on (ws://127\.0\.0\.1:\d+)", 60).group(1)
    # A client offering only the old name is refused in the handshake, and the start line says so.
    assert "subprotocol foxglove.sdk.v1" in log.read_text() and "foxglove.websocket.v1" in log.read_text()
    with pytest.raises(InvalidStatus) as refused:
        connect(url, subprotocols=["foxglove.websocket.v1"], open_timeout=10, proxy=None)
    assert refused.value.response.status_code == 400

    received: dict[str, list] = {t: [] for t in (*TOPICS, "diagnostics")}
    # foxglove-sdk 0.30 speaks the v1 protocol under its new name foxglove.sdk.v1 (identical to
    # foxglove.websocket.v1, which it refuses); current Foxglove clients offer both, as here.
    with connect(url, subprotocols=SUBPROTOCOLS, open_timeout=10, proxy=None) as ws:
        assert ws.subprotocol in SUBPROTOCOLS
        info = json.loads(ws.recv(timeout=10))
        assert info["op"] == "serverInfo" and info["name"] == "pac live_view"
        channels = {}
        deadline = time.monotonic() + 10
        while len(channels) < len(TOPICS) + 1 and time.monotonic() < deadline:
            frame = json.loads(ws.recv(timeout=10))
            if frame["op"] == "advertise":
                for ch in frame["channels"]:
                    channels[ch["id"]] = ch
        by_topic = {ch["topic"]: ch for ch in channels.values()}
        # ... and every node's health, for Foxglove's diagnostics panels
        assert sorted(by_topic) == sorted([*(f"/{t}" for t in TOPICS), "/diagnostics"])
        assert by_topic.pop("/diagnostics")["schemaName"] == "diagnostic_msgs/msg/DiagnosticArray"
        for topic, ch in by_topic.items():
            assert ch["encoding"] == "cdr" and ch["schemaEncoding"] == "ros2msg"
            assert ch["schemaName"] == bag.topics[topic[1:]].typename
            assert "MSG: std_msgs/Header" in ch["schema"]  # dependencies included: Foxglove can decode
        assert subscribed_topics(env) == []  # nobody watches yet: not even a matched reader
        subscriptions = dict(enumerate(channels.values(), start=1))
        ws.send(
            json.dumps(
                {
                    "op": "subscribe",
                    "subscriptions": [{"id": i, "channelId": ch["id"]} for i, ch in subscriptions.items()],
                }
            )
        )
        replay = subprocess.Popen(
            ["ros2", "run", "pac_rig", "replay", str(bag_path), "--topics", *TOPICS, "--wait-for", "1"],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            text=True,
            env=env,
        )
        processes.append(replay)
        started = time.monotonic()
        while True:
            try:
                frame = ws.recv(timeout=0.5)
            except TimeoutError:
                if replay.poll() is not None:
                    break
                assert time.monotonic() - started < 60, "replay did not finish"
                continue
            if isinstance(frame, bytes) and frame[0] == MESSAGE_DATA:
                sub_id, log_time = struct.unpack_from("<IQ", frame, 1)
                topic = subscriptions[sub_id]["topic"][1:]
                msg = typestore().deserialize_cdr(frame[13:], subscriptions[sub_id]["schemaName"])
                received[topic].append((log_time, msg))
        assert replay.returncode == 0, replay.stderr.read()

    deadline = time.monotonic() + 10  # the client has gone: so have the live view's subscriptions
    while subscribed_topics(env):
        assert time.monotonic() < deadline

    # The live view's own status came through, not decimated (one a second from every node).
    assert any(s.name == "live_view: node" for _, m in received["diagnostics"] for s in m.status)
    replay_seconds = 2.0
    for topic in TOPICS:
        got = received[topic]
        # Decimated to rate_hz per topic on average (the full stream is 2000), live all along.
        assert 0.5 * rate_hz * replay_seconds <= len(got) <= rate_hz * replay_seconds + 3, (topic, len(got))
        ticks = np.array([m.tick for _, m in got])
        assert np.all(np.diff(ticks) > 0)
    # The values a user plots (F, u, k_hat) are the recorded ones, bit for bit.
    for topic, field in (
        ("plant_truth", "contact_force"),
        ("command", "u"),
        ("estimate", "stiffness_hat"),
        ("measurement", "z1"),
    ):
        data = bag.topics[topic]
        index = {int(t): i for i, t in enumerate(data["tick"])}
        for _, msg in received[topic]:
            assert getattr(msg, field) == data[field][index[msg.tick]], (topic, field, msg.tick)

    assert stop(viewer) == 0
    assert re.search(r"stopped \(measurement=\d+", log.read_text()), log.read_text()


def test_live_view_refuses_a_bad_port_with_one_line(domain_id):
    proc = subprocess.run(
        ["ros2", "run", "pac_rig", "live_view", "--ros-args", "-p", "port:=70000"],
        capture_output=True,
        text=True,
        timeout=60,
        env=node_env(domain_id),
    )
    assert proc.returncode == 2
    errors = [line for line in proc.stderr.splitlines() if "invalid parameter" in line]
    assert errors == ["live_view: invalid parameter 'port' = 70000: allowed an integer in [0, 65535]"], (
        proc.stderr
    )
