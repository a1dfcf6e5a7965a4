#!/usr/bin/env python3
"""What the live view costs: its CPU and what a Foxglove client receives, over a real-time rig.

Usage: scripts/with_env.sh python scripts/bench_live_view.py [--seconds 10]

Starts plant (real time, 1 kHz), observer and controller in a free ROS domain, then for each
configuration a ``live_view`` (port 0) with or without a subscribed WebSocket client, and prints
a markdown table. Every process started here is stopped by PID, also on failure.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

from websockets.sync.client import connect

from pac_common import markdown
from pac_rig.launcher import Rig, node_env

SUBPROTOCOLS = ["foxglove.sdk.v1", "foxglove.websocket.v1"]


def cpu_seconds(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")  # utime + stime


def client(url: str, stop: threading.Event, counts: dict) -> None:
    with connect(url, subprotocols=SUBPROTOCOLS, proxy=None) as ws:
        channels = {}
        while len(channels) < 4:
            frame = json.loads(ws.recv(timeout=10))
            if frame["op"] == "advertise":
                channels.update({ch["id"]: ch for ch in frame["channels"]})
        subs = [{"id": i, "channelId": cid} for i, cid in enumerate(channels, start=1)]
        ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
        while not stop.is_set():
            try:
                frame = ws.recv(timeout=0.2)
            except TimeoutError:
                continue
            if isinstance(frame, bytes) and frame[0] == 1:
                counts["n"] += 1


def measure(env: dict, rate_hz: float, with_client: bool, seconds: float, log: Path) -> tuple[float, float]:
    with open(log, "wb") as out:
        proc = subprocess.Popen(
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
    stop, counts, thread = threading.Event(), {"n": 0}, None
    try:
        deadline = time.monotonic() + 60
        while not (found := re.search(r"on (ws://\S+)", log.read_text())):
            if time.monotonic() > deadline or proc.poll() is not None:
                raise RuntimeError(log.read_text())
            time.sleep(0.05)
        if with_client:
            thread = threading.Thread(target=client, args=(found.group(1), stop, counts), daemon=True)
            thread.start()
        time.sleep(2.0)  # settle: process start-up and subscription are not measured
        c0, n0, t0 = cpu_seconds(proc.pid), counts["n"], time.monotonic()
        time.sleep(seconds)
        c1, n1, t1 = cpu_seconds(proc.pid), counts["n"], time.monotonic()
        return 100 * (c1 - c0) / (t1 - t0), (n1 - n0) / (t1 - t0)
    finally:
        stop.set()
        if thread is not None:
            thread.join(timeout=5)
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
            try:
                proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()


def main() -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--seconds", type=float, default=10.0, help="measured seconds per configuration")
    args = parser.parse_args()
    if not 1.0 <= args.seconds <= 600.0:
        print(f"bench_live_view: invalid --seconds {args.seconds:g}: allowed [1, 600]", file=sys.stderr)
        return 2
    import domain_coordinator

    rows = []
    with tempfile.TemporaryDirectory() as tmp, domain_coordinator.domain_id() as did:
        rig = Rig(Path(tmp) / "bag", duration=0.0, domain_id=did, log_dir=Path(tmp) / "logs", record=False)
        try:
            rig.start()
            deadline = time.monotonic() + 60
            while "real-time loop running" not in rig.processes["plant"].log():
                if time.monotonic() > deadline:
                    raise RuntimeError(rig.processes["plant"].log())
                time.sleep(0.05)
            for rate_hz, with_client in ((50.0, False), (50.0, True), (1000.0, True)):
                cpu, rate = measure(node_env(did), rate_hz, with_client, args.seconds, Path(tmp) / "lv.log")
                rows.append((rate_hz, with_client, cpu, rate))
        finally:
            rig.stop(grace=5.0)
    print(f"\nlive_view over a 1 kHz real-time rig ({args.seconds:g} s per row)\n")
    header = ["rate_hz", "client subscribed", "live_view CPU [%]", "messages/s to the client (4 topics)"]
    cells = [
        [f"{rate_hz:g}", "yes" if with_client else "no", f"{cpu:.1f}", f"{rate:.0f}"]
        for rate_hz, with_client, cpu, rate in rows
    ]
    print(markdown.table(header, cells, ["r", "l", "r", "r"]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
