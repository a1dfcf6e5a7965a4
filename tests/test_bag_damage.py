"""Damaged bags through every bag reader: info, report, recover and replay's reader.

Each damage gives one line per problem (``<tool>: ...``), exit status 1, what was readable and
no traceback; ``recover`` salvages every intact chunk and writes no message that was not in the
bag byte for byte.  The bags are real MCAP written by the offline simulator with small chunks
(so a bag has many), and what ``recover`` writes is read back by the MCAP library's own reader
with its CRC checks.  The mutation fuzz test runs a fixed set of examples (derandomized);
``PAC_FUZZ_EXAMPLES=2000`` runs more, ``PAC_FUZZ_RANDOM=1`` new ones each time.
"""

from __future__ import annotations

import contextlib
import io
import math
import os
import shutil
import struct
import time
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from mcap.reader import make_reader

from pac_analysis import info, recover, report
from pac_bag import cdr, mcap_writer
from pac_bag.mcap_writer import McapWriter
from pac_bag.names import qualified
from pac_bag.reader import BagError, read_bag
from pac_bag.typestore import typestore
from pac_bag.writer import BagWriter
from pac_common import messages
from pac_rig import replay
from pac_rig.simulate import scenario_from_flat, simulate_to_bag

pytestmark = pytest.mark.offline

#: Small chunks, so a one-second bag has dozens and a damaged one leaves most intact.
CHUNK_BYTES = 16 << 10


@pytest.fixture(scope="module")
def good_bag(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("good") / "good"
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(mcap_writer, "CHUNK_SIZE", CHUNK_BYTES)
        simulate_to_bag(scenario_from_flat({"duration": 1.0}), path, compression="zstd")
    return path


def mcap_file(bag: Path) -> Path:
    (file,) = bag.glob("*.mcap")
    return file


def independent_messages(file: Path) -> Counter:
    """(topic, log time, data) of every message, by the MCAP library's reader with CRC checks."""
    with open(file, "rb") as stream:
        reader = make_reader(stream, validate_crcs=True)
        return Counter((ch.topic, m.log_time, bytes(m.data)) for _, ch, m in reader.iter_messages())


def chunks(file: Path) -> list:
    """The chunk indexes of a closed file, by the MCAP library."""
    with open(file, "rb") as stream:
        summary = make_reader(stream).get_summary()
    assert summary is not None
    return sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)


def chunk_message_counts(file: Path, chunk) -> Counter:
    """Messages per topic in one chunk, from its message index records (located by the MCAP
    library's chunk index, parsed per the specification: channel id, then 16 bytes a message)."""
    with open(file, "rb") as stream:
        summary = make_reader(stream).get_summary()
    assert summary is not None
    data = file.read_bytes()
    counts: Counter = Counter()
    for channel_id, offset in chunk.message_index_offsets.items():
        op, _, channel, size = struct.unpack_from("<BQHI", data, offset)
        assert op == 0x07 and channel == channel_id
        counts[messages_topic(summary.channels[channel_id].topic)] += size // 16
    return counts


def messages_topic(name: str) -> str:
    return name.lstrip("/")


def copy_bag(good: Path, dest: Path) -> Path:
    shutil.copytree(good, dest)
    return dest


def flip(file: Path, offset: int, mask: int = 0xFF) -> None:
    data = bytearray(file.read_bytes())
    data[offset] ^= mask
    file.write_bytes(bytes(data))


def run(main, *args) -> tuple[int, str, str]:
    """A tool's main in this process: (exit status, stdout, stderr)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main([str(a) for a in args])
    return code, out.getvalue(), err.getvalue()


def problem_lines(tool: str, stderr: str) -> list[str]:
    lines = stderr.strip().splitlines()
    assert lines, f"{tool}: no problem said"
    assert all(line.startswith(f"{tool}: ") for line in lines), stderr
    assert "Traceback" not in stderr
    return lines


def test_one_flipped_byte_in_a_compressed_chunk_loses_that_chunk_only(good_bag, tmp_path):
    """The old readers crashed (ZstdError through recovery.iter_records), recover included."""
    bag = copy_bag(good_bag, tmp_path / "flipped")
    file = mcap_file(bag)
    index = chunks(file)
    assert len(index) > 10
    damaged = index[len(index) // 2]
    flip(file, damaged.chunk_start_offset + damaged.chunk_length - damaged.compressed_size // 2)
    lost = chunk_message_counts(file, damaged)
    original = read_bag(good_bag)

    code, out, err = run(info.main, bag)
    assert code == 1
    lines = problem_lines("info", err)
    assert any(f"chunk at byte {damaged.chunk_start_offset}" in line and "dropped" in line for line in lines)
    damaged_bag = read_bag(bag)
    for topic, data in original.topics.items():
        assert len(damaged_bag.topics[topic]) == len(data) - lost[topic], topic

    code, out, err = run(recover.main, bag, "--out", tmp_path / "recovered")
    assert code == 1
    assert any("dropped" in line for line in problem_lines("recover", err))
    recovered = independent_messages(mcap_file(tmp_path / "recovered"))
    before = independent_messages(mcap_file(good_bag))
    assert not recovered - before  # nothing the bag did not hold, byte for byte
    assert sum(recovered.values()) == sum(before.values()) - sum(lost.values())

    code, _, err = run(report.main, bag, "--out", tmp_path / "report", "--from", "0.2")
    assert code == 1
    problem_lines("report", err)


def test_a_bit_flip_in_an_uncompressed_chunk_is_dropped_not_rewritten(tmp_path):
    """recover kept bit-flipped records of a chunk that failed its CRC and wrote them back with
    fresh checksums (a tick of 4503599627370642)."""
    good = tmp_path / "plain"
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(mcap_writer, "CHUNK_SIZE", CHUNK_BYTES)
        simulate_to_bag(scenario_from_flat({"duration": 0.3}), good, compression="none")
    bag = copy_bag(good, tmp_path / "flipped")
    file = mcap_file(bag)
    damaged = chunks(file)[1]
    # a byte in the middle of the chunk's records: inside some message's data
    flip(file, damaged.chunk_start_offset + damaged.chunk_length - damaged.compressed_size // 2, 0x40)
    code, _, err = run(recover.main, bag, "--out", tmp_path / "recovered")
    assert code == 1
    assert any("fail the chunk's CRC" in line for line in problem_lines("recover", err))
    recovered = independent_messages(mcap_file(tmp_path / "recovered"))
    assert not recovered - independent_messages(mcap_file(good))
    ticks = read_bag(tmp_path / "recovered").topics["plant_truth"]["tick"]
    assert ticks.max() < 300


@pytest.mark.parametrize("size", [0, 8, 9, 20])
def test_a_file_cut_to_its_magic_is_one_line_for_every_reader(good_bag, tmp_path, size):
    """Cut to the 8-byte magic, the old readers gave a TypeError."""
    bag = copy_bag(good_bag, tmp_path / "cut")
    file = mcap_file(bag)
    file.write_bytes(file.read_bytes()[:size])
    for tool, args in (
        (info.main, ()),
        (recover.main, ("--out", tmp_path / "recovered")),
        (report.main, ("--out", tmp_path / "report")),
    ):
        code, _, err = run(tool, bag, *args)
        assert code == 1
        (line,) = problem_lines(tool.__module__.rsplit(".", 1)[1], err)
        assert "no readable message" in line or "not an MCAP file" in line
    warnings: list[str] = []
    if size < 8:
        with pytest.raises(BagError):
            replay.replayable(bag, ["measurement"], warnings)
    else:
        assert replay.replayable(bag, ["measurement"], warnings) == []
        assert any("good.mcap" in w for w in warnings), warnings
    assert not (tmp_path / "recovered").exists()


def two_types_on_one_topic(good: Path, path: Path) -> None:
    """A bare MCAP file whose /measurement has two channels of different types: ticks 0, 3, 6, 9
    are estimates (from the good bag), the others measurements."""
    store = typestore()
    writer = McapWriter(path)
    channels, samples = {}, {}
    for topic in ("measurement", "estimate"):
        typename = messages.TOPICS[topic]
        msgdef, _ = store.generate_msgdef(typename, ros_version=2)
        schema = writer.add_schema(typename, "ros2msg", msgdef.encode())
        channels[topic] = writer.add_channel(qualified("measurement"), schema, "cdr", {})
        samples[topic] = [data for t, _, _, data in _records(good) if t == topic]
    for tick in range(10):
        topic = "measurement" if tick % 3 else "estimate"
        writer.add_message(channels[topic], tick * 1000, samples[topic][tick])
    writer.close()


def test_two_types_on_one_topic_are_reported_not_a_key_error(good_bag, tmp_path):
    path = tmp_path / "mixed.mcap"
    two_types_on_one_topic(good_bag, path)
    bag = read_bag(path)
    assert list(bag.topics["measurement"]["tick"]) == [1, 2, 4, 5, 7, 8]
    (line,) = bag.warnings
    assert "several types" in line and f"4 of {messages.TOPICS['estimate']}" in line
    code, out, err = run(info.main, path)
    assert code == 1 and "measurement" in out
    problem_lines("info", err)
    code, _, err = run(recover.main, path, "--out", tmp_path / "recovered")
    assert code == 1
    assert any("4 messages of" in line and "not recovered" in line for line in problem_lines("recover", err))
    assert len(read_bag(tmp_path / "recovered").topics["measurement"]) == 6
    warnings: list[str] = []
    assert [r.tick for r in replay.replayable(path, ["measurement"], warnings)] == [1, 2, 4, 5, 7, 8]
    assert any("4 messages not replayed" in w for w in warnings)


def test_a_type_metadata_yaml_names_differently_is_said_and_the_topic_kept(good_bag, tmp_path):
    """recover dropped the whole topic, exit 0; info said '0 of 1000 readable'."""
    bag = copy_bag(good_bag, tmp_path / "renamed")
    meta = bag / "metadata.yaml"
    text = meta.read_text()
    assert "type: pac_interfaces/msg/FrameMeasurement" in text
    meta.write_text(text.replace("type: pac_interfaces/msg/FrameMeasurement", "type: other_pkg/msg/Thing"))
    code, out, err = run(info.main, bag)
    assert code == 1
    lines = problem_lines("info", err)
    assert any("metadata.yaml declares other_pkg/msg/Thing" in line for line in lines), lines
    assert len(read_bag(bag).topics["measurement"]) == len(read_bag(good_bag).topics["measurement"])
    code, _, err = run(recover.main, bag, "--out", tmp_path / "recovered")
    assert code == 1
    problem_lines("recover", err)
    before = independent_messages(mcap_file(good_bag))
    assert independent_messages(mcap_file(tmp_path / "recovered")) == before


def test_a_non_numeric_message_count_costs_that_count_only(good_bag, tmp_path):
    bag = copy_bag(good_bag, tmp_path / "counts")
    meta = bag / "metadata.yaml"
    data = yaml.safe_load(meta.read_text())
    entries = data["rosbag2_bagfile_information"]["topics_with_message_count"]
    entries[0]["message_count"] = "many"
    entries[1]["message_count"] = 5000  # more than the bag holds: must still be checked
    meta.write_text(yaml.safe_dump(data))
    warnings = read_bag(bag).warnings
    first, second = (
        qualified_name.lstrip("/") for qualified_name in (e["topic_metadata"]["name"] for e in entries[:2])
    )
    assert any(f"'{first}': metadata.yaml message_count 'many' is not a count" in w for w in warnings), (
        warnings
    )
    assert any(f"'{second}':" in w and "of 5000 messages readable" in w for w in warnings), warnings


def test_report_keeps_two_bags_with_the_same_folder_name(good_bag, tmp_path):
    a = copy_bag(good_bag, tmp_path / "a" / "run")
    b = copy_bag(good_bag, tmp_path / "b" / "run")
    code, out, err = run(report.main, a, b, "--out", tmp_path / "report", "--from", "0.2")
    assert code == 0, err
    assert report.bag_names([a, b]) == ["a_run", "b_run"]
    assert "| a_run | b_run |" in out.replace("  ", " ") or ("a_run" in out and "b_run" in out)
    assert (tmp_path / "report" / "a_run.png").is_file() and (tmp_path / "report" / "b_run.png").is_file()
    assert report.bag_names([a, a]) == ["run", "run_2"]


def with_nan_forces(good: Path, dest: Path) -> Path:
    """The good bag with every plant_truth contact force NaN (the CDR edited in place)."""
    store = typestore()
    typename = messages.TOPICS["plant_truth"]
    field, offset = cdr.layout(store, typename).dtype.fields["contact_force"][:2]
    assert field == np.dtype("<f8")
    bag = read_bag(good)
    with BagWriter(dest, {"source": "offline"}) as writer:
        for topic, _, log_time, data in _records(good):
            if topic == "plant_truth":
                edited = bytearray(data)
                struct.pack_into("<d", edited, offset, math.nan)
                data = bytes(edited)
            writer.write_raw(topic, data, log_time)
    assert len(read_bag(dest).topics["plant_truth"]) == len(bag.topics["plant_truth"])
    return dest


def _records(bag: Path):
    from pac_bag.recovery import iter_records

    return list(iter_records(bag, []))


def test_a_bag_whose_forces_are_all_nan_is_not_contact_lost_0_percent(good_bag, tmp_path):
    bag = with_nan_forces(good_bag, tmp_path / "nan")
    code, out, err = run(report.main, bag, "--out", tmp_path / "report", "--from", "0.2")
    assert code == 1
    lines = problem_lines("report", err)
    assert any("contact forces not finite" in line for line in lines), lines
    import json

    metrics = json.loads((tmp_path / "report" / "metrics.json").read_text())["runs"]["nan"]["metrics"]
    assert metrics["contact_loss_percent"] is None  # NaN, written as null


def test_recover_writes_under_a_temporary_name(good_bag, tmp_path, monkeypatch):
    """A failure while writing leaves nothing under the name asked for."""
    from pac_bag import writer

    def full_disk(self, *args, **kwargs):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(writer.BagWriter, "write_raw", full_disk)
    code, _, err = run(recover.main, good_bag, "--out", tmp_path / "recovered")
    assert code == 2
    (line,) = problem_lines("recover", err)
    assert "No space left on device" in line
    assert list(tmp_path.iterdir()) == []


def test_recover_of_the_current_directory_names_its_output(good_bag, tmp_path, monkeypatch):
    bag = copy_bag(good_bag, tmp_path / "here")
    monkeypatch.chdir(bag)
    code, out, err = run(recover.main, ".")
    assert code == 0, err
    assert (tmp_path / "here_recovered" / "here_recovered.mcap").is_file()


# -- fuzzing: mutated bags through every reader -----------------------------------------------------


def _fuzz_settings():
    return settings(
        max_examples=int(os.environ.get("PAC_FUZZ_EXAMPLES", "25")),
        derandomize=not os.environ.get("PAC_FUZZ_RANDOM"),
        deadline=None,
        suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
    )


#: One mutation: flip bytes, cut the file, or overwrite a range (a damaged chunk).
MUTATION = st.one_of(
    st.tuples(
        st.just("flip"), st.lists(st.tuples(st.floats(0, 1), st.integers(1, 255)), min_size=1, max_size=8)
    ),
    st.tuples(st.just("cut"), st.floats(0, 1)),
    st.tuples(st.just("zero"), st.tuples(st.floats(0, 1), st.integers(1, 4096))),
)


def mutate(data: bytes, mutation) -> bytes:
    kind, what = mutation
    out = bytearray(data)
    if kind == "flip":
        for where, mask in what:
            out[min(int(where * len(out)), len(out) - 1)] ^= mask
    elif kind == "cut":
        out = out[: int(what * len(out))]
    else:
        start = int(what[0] * len(out))
        out[start : start + what[1]] = bytes(len(out[start : start + what[1]]))
    return bytes(out)


@pytest.mark.slow
@_fuzz_settings()
@given(mutation=MUTATION, keep_metadata=st.booleans())
def test_fuzz_mutated_bags_through_every_reader(good_bag, tmp_path_factory, mutation, keep_metadata):
    """Every reader on a mutated bag: exit 0 or 1, one line per problem (1: at least one), no
    traceback, done in seconds; recover writes only messages the bag held, byte for byte."""
    work = tmp_path_factory.mktemp("fuzz")
    bag = copy_bag(good_bag, work / "bag")
    if not keep_metadata:
        (bag / "metadata.yaml").unlink()
    file = mcap_file(bag)
    file.write_bytes(mutate(file.read_bytes(), mutation))
    started = time.monotonic()
    for name, tool, args in (
        ("info", info.main, ()),
        ("recover", recover.main, ("--out", work / "recovered")),
        ("report", report.main, ("--out", work / "report", "--from", "0.2")),
    ):
        code, _, err = run(tool, bag, *args)
        assert code in (0, 1), (name, err)
        if code == 1 or err:
            problem_lines(name, err)
    if (work / "recovered").exists():
        recovered = independent_messages(mcap_file(work / "recovered"))
        assert not recovered - independent_messages(mcap_file(good_bag))
    warnings: list[str] = []
    try:
        replay.replayable(bag, ["measurement", "estimate"], warnings)
    except BagError as exc:
        assert "\n" not in str(exc)
    assert all("\n" not in w for w in warnings)
    assert time.monotonic() - started < 30.0


# -- messages lost before the recorder -----------------------------------------------------------


@pytest.mark.live
def test_messages_lost_to_a_stalled_recorder_are_counted_in_the_bag(tmp_path, domain_id, processes):
    """A recorder that cannot run for 3 s while 1 kHz samples arrive (stopped with SIGSTOP, as a
    starved process would be): the publisher's keep-last 1000 drops what the recorder had not
    acknowledged. The loss was silent; now the recorder counts DDS's message-lost events, stores
    them in the bag and every reader reports them. The stall is longer than the recorder's
    idle_timeout: the recorder's own silence does not close the bag, it records to the end."""
    import signal
    import subprocess

    from conftest import ROS2

    source = tmp_path / "source"
    simulate_to_bag(scenario_from_flat({"duration": 6.0}), source)
    env = {**os.environ, "ROS_DOMAIN_ID": str(domain_id)}
    bag = tmp_path / "recorded"
    with open(tmp_path / "recorder.log", "wb") as log:  # the process keeps its own descriptor
        recorder = subprocess.Popen(
            [
                ROS2,
                "run",
                "pac_rig",
                "recorder",
                "--ros-args",
                "-p",
                f"bag_path:={bag}",
                "-p",
                "topics:=plant_truth",
                "-p",
                "idle_timeout:=2.0",
            ],
            stdout=log,
            stderr=subprocess.STDOUT,
            env=env,
        )
    processes.append(recorder)
    player = subprocess.Popen(
        [ROS2, "run", "pac_rig", "replay", str(source), "--topics", "plant_truth", "--wait-for", "1"],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        env=env,
    )
    processes.append(player)
    time.sleep(6.0)  # start-up and discovery, then the first seconds of the replay
    recorder.send_signal(signal.SIGSTOP)
    time.sleep(3.0)
    recorder.send_signal(signal.SIGCONT)
    player.wait(timeout=60)
    assert recorder.wait(timeout=30) == 0  # closed by its idle_timeout, once the replay ended
    text = (tmp_path / "recorder.log").read_text()
    bag_data = read_bag(bag)
    recorded = len(bag_data.topics["plant_truth"])
    lost_lines = [w for w in bag_data.warnings if "lost before they reached the recorder" in w]
    print(f"\nrecorded {recorded} of 6000; {lost_lines}; {text.strip().splitlines()[-1]}")
    assert bag_data.topics["plant_truth"]["tick"].max() == 5999, text[-1500:]
    if recorded < 6000:  # the stall lost samples: they must be counted, not silent
        (line,) = lost_lines
        assert f"'plant_truth': {6000 - recorded} messages lost" in line
        code, _, err = run(info.main, bag)
        assert code == 1 and "lost before they reached the recorder" in err
    else:
        pytest.skip("this host delivered every sample despite the stall: nothing lost to count")


def test_the_recorders_health_is_error_while_messages_are_lost():
    from pac_common.diagnostics import ERROR, OK, recorder_status

    counters = {"state": "recording", "messages": 10, "bag_bytes": 100, "queued": 0}
    assert recorder_status("recorder", counters, None).level == OK
    lost = recorder_status("recorder", {**counters, "lost_messages": 13, "lost_plant_truth": 13}, None)
    assert lost.level == ERROR
    assert "13 messages lost before they reached the recorder (plant_truth 13)" in lost.message
