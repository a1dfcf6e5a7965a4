"""Bags: vectorised CDR byte for byte, bulk == message-by-message bags, the
ros2 bag layout (names, QoS, compression) read by three readers, old bags, damaged bags."""

import json
import re
import shutil
import subprocess

import numpy as np
import pytest
import yaml
from mcap.reader import make_reader
from mcap.stream_reader import StreamReader
from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from pac_bag import cdr
from pac_bag.mcap_writer import COMPRESSIONS
from pac_bag.reader import read_bag
from pac_bag.recovery import iter_records
from pac_bag.typestore import ensure_type, typestore, writer_typestore
from pac_bag.writer import BagWriter
from pac_common import messages
from pac_rig import simulate
from pac_rig.closed_loop import run
from pac_rig.simulate import scenario_from_flat, simulate_to_bag, tick_fields

pytestmark = pytest.mark.offline

RNG = np.random.default_rng(5)


def random_columns(lay: cdr.CdrLayout, n: int) -> dict[str, np.ndarray]:
    """Random values of every field of a layout (full range of integers, signed floats)."""
    cols = {}
    for path in lay.fields:
        base, shape = lay.dtype.fields[path][0].base, lay.dtype.fields[path][0].shape
        size = (n, *shape)
        if base.kind == "b":
            cols[path] = RNG.random(size) < 0.5
        elif base.kind in "iu":
            info = np.iinfo(base)
            cols[path] = RNG.integers(info.min, info.max, size=size, dtype=base, endpoint=True)
        elif base.kind == "f":
            cols[path] = (RNG.standard_normal(size) * 10.0 ** RNG.integers(-5, 5, size)).astype(base)
    return cols


def nested(columns: dict, i: int, strings: dict[str, str]) -> dict:
    """Message i of flat columns as the nested field dictionary rosbags objects are made from."""
    out: dict = {}
    for path, values in list(columns.items()) + [(p, [s]) for p, s in strings.items()]:
        keys = path.split(".")
        node = out
        for key in keys[:-1]:
            node = node.setdefault(key, {})
        value = values[i] if len(values) > 1 else values[0]
        node[keys[-1]] = value.item() if isinstance(value, np.generic) else value
    return out


def assert_bytes_equal_rosbags(store, typename: str, n: int = 40, strings: dict[str, str] | None = None):
    strings = strings or {}
    lay = cdr.layout(store, typename, {p: len(s) for p, s in strings.items()})
    cols = random_columns(lay, n)
    ours = cdr.serialize_many(store, typename, {**cols, **strings}, n)
    factory = messages.RosbagsFactory(store)
    assert ours.shape == (n, lay.size)
    for i in range(n):
        theirs = store.serialize_cdr(factory.make(typename, nested(cols, i, strings)), typename)
        assert ours[i].tobytes() == bytes(theirs), f"{typename} message {i} strings={strings}"


@pytest.mark.parametrize("typename", sorted(messages.TOPICS.values()))
@pytest.mark.parametrize("frame_id", ["", "a", "ab", "abc", "abcdefg"])
def test_vectorised_cdr_is_byte_for_byte_rosbags(typename, frame_id):
    """Every pac message, with frame_ids of every length mod 8 that shifts what follows (and its
    other string fields, e.g. RunStatus.catenary_model, one length less)."""
    store = typestore()
    strings = dict.fromkeys(cdr.string_fields(store, typename), frame_id[:-1])
    assert_bytes_equal_rosbags(store, typename, strings={**strings, "header.frame_id": frame_id})


@pytest.mark.parametrize("typename", sorted(set(messages.WATCHED_TOPICS.values())))
def test_writer_store_defines_each_type_as_the_jazzy_store(typename):
    """The writer's small store (pac types, then what a topic needs from the installed .msg files)
    gives each type the definition, message text and hash of rosbags' whole Jazzy store, and knows
    no Jazzy type it was not asked for."""
    full = typestore()
    small = writer_typestore()
    ensure_type(small, typename)
    assert typename in small.fielddefs
    for name in small.fielddefs:
        assert small.fielddefs[name] == full.fielddefs[name], name
        assert small.generate_msgdef(name, ros_version=2) == full.generate_msgdef(name, ros_version=2)
        assert small.hash_rihs01(name) == full.hash_rihs01(name)
    assert len(small.fielddefs) < 20


def test_writer_store_leaves_an_unknown_type_to_the_stores_error():
    small = writer_typestore()
    ensure_type(small, "no_such_pkg/msg/Nothing")
    assert "no_such_pkg/msg/Nothing" not in small.fielddefs
    with pytest.raises(Exception, match="Nothing"):
        small.generate_msgdef("no_such_pkg/msg/Nothing", ros_version=2)


def test_layout_follows_any_msg_definition_with_odd_alignments():
    """A type nothing in pac hand-codes: 1/2/4/8-byte fields after odd offsets, a string in the
    middle, nested types, fixed arrays of every width; plus one field added later."""
    store = get_typestore(Stores.ROS2_JAZZY)
    store.register(get_types_from_msg("uint8 a\nint16[3] b\nbool c", "test_pkg/msg/Inner"))
    definition = (
        "uint8 first\nfloat64 x\nstring name\nint16 s\nuint32[3] u\nbool flag\nint64 big\n"
        "test_pkg/Inner inner\nfloat32 f\nint8[5] small\nbuiltin_interfaces/Time t\nuint64 last"
    )
    store.register(get_types_from_msg(definition, "test_pkg/msg/Odd"))
    for name in ("", "x", "xyz", "hello"):
        assert_bytes_equal_rosbags(store, "test_pkg/msg/Odd", strings={"name": name})
    store.register(get_types_from_msg(definition + "\nuint8 added", "test_pkg/msg/OddPlus"))
    assert_bytes_equal_rosbags(store, "test_pkg/msg/OddPlus", strings={"name": "ab"})


def test_no_fixed_layout_is_refused():
    store = get_typestore(Stores.ROS2_JAZZY)
    store.register(get_types_from_msg("float64[] values", "test_pkg/msg/Seq"))
    with pytest.raises(cdr.LayoutError, match="sequence"):
        cdr.layout(store, "test_pkg/msg/Seq")
    with pytest.raises(cdr.LayoutError, match="different lengths"):
        cdr.serialize_many(typestore(), messages.FRAME_MEASUREMENT, {"header.frame_id": ["a", "bb"]}, 2)


def mcap_records(bag):
    """(topic, log time, publish time, data) of every message in file order, via the mcap library."""
    (file,) = bag.glob("*.mcap")
    with open(file, "rb") as stream:
        reader = make_reader(stream, validate_crcs=True)  # chunk CRCs are written
        return [
            (channel.topic, m.log_time, m.publish_time, m.data)
            for _, channel, m in reader.iter_messages(log_time_order=False)
        ]


def test_bulk_bag_equals_the_same_run_written_message_by_message(tmp_path, monkeypatch):
    """The fast path (columns -> CDR with numpy -> whole chunks) and the path the recorder takes
    (one message at a time; CDR from the rosbags serialiser) give the same bag content."""
    monkeypatch.setattr(simulate, "WRITE_BLOCK", 500)  # blocks end mid-run and mid-chunk
    scenario = scenario_from_flat({"duration": 1.3, "command_delay_ticks": 2})
    simulate_to_bag(scenario, tmp_path / "bulk", label="x")
    rate, duration = scenario.loop.rate_hz, scenario.loop.duration
    line = simulate.plant_line(scenario)  # the plant's line, as run_status names it

    def run_status(bag, tick, state):
        stamp = messages.tick_stamp_ns(tick, rate)
        bag.write("run_status", messages.run_status_fields(tick, state, duration, stamp, *line), stamp)

    with BagWriter(tmp_path / "single", {"source": "offline", "label": "x"}) as bag:
        run_status(bag, 0, messages.RUN_RUNNING)
        for rec in run(scenario):
            stamp = messages.tick_stamp_ns(rec.measurement.tick, rate)
            for topic, fields in tick_fields(rec, scenario).items():
                bag.write(topic, fields, stamp)
        run_status(bag, 1299, messages.RUN_ENDED)
    bulk, single = mcap_records(tmp_path / "bulk"), mcap_records(tmp_path / "single")
    assert len(bulk) == 4 * 1300 + 2  # the loop's four topics per tick, the run's start and end
    assert bulk == single
    meta = [yaml.safe_load((tmp_path / b / "metadata.yaml").read_text()) for b in ("bulk", "single")]
    for m in meta:
        del m["rosbag2_bagfile_information"]["custom_data"]
        for name in ("relative_file_paths", "files"):
            del m["rosbag2_bagfile_information"][name]  # the file names differ
    assert meta[0] == meta[1]


def test_merging_topics_of_different_rates_orders_by_log_time(tmp_path):
    """write_many of topics with different log times: one stream in log-time order, ties in call order."""
    store = typestore()
    a_times = np.arange(0, 100, 10, dtype=np.int64)
    b_times = np.arange(5, 100, 20, dtype=np.int64).repeat(2)  # duplicates, and ties with nothing
    with BagWriter(
        tmp_path / "m", topics={"a": messages.FRAME_MEASUREMENT, "b": messages.ACTUATOR_COMMAND}
    ) as bag:
        for topic, times in (("a", a_times), ("b", b_times)):
            lay = cdr.layout(store, bag._topics[topic].typename)
            cols = random_columns(lay, times.size)
            cols["tick"] = np.arange(times.size, dtype=np.uint64)
            bag.write_many(topic, cols, times)
    got = mcap_records(tmp_path / "m")
    assert [t for _, t, _, _ in got] == sorted(np.concatenate([a_times, b_times]).tolist())
    assert [messages.cdr_tick(d) for topic, _, _, d in got if topic == "/b"] == list(range(b_times.size))


@pytest.fixture(scope="module")
def bags_by_compression(tmp_path_factory):
    root = tmp_path_factory.mktemp("compression")
    for compression in COMPRESSIONS:
        simulate_to_bag(scenario_from_flat({"duration": 3.0}), root / compression, compression=compression)
    return root


@pytest.mark.parametrize("compression", COMPRESSIONS)
@pytest.mark.slow
def test_bags_read_by_rosbags_mcap_and_stream_readers_alike(bags_by_compression, compression):
    bag = bags_by_compression / compression
    (file,) = bag.glob("*.mcap")
    with open(file, "rb") as stream:
        summary = make_reader(stream).get_summary()
    assert {c.topic for c in summary.channels.values()} == {f"/{t}" for t in messages.TOPICS}
    assert {s.encoding for s in summary.schemas.values()} == {"ros2msg"}
    assert summary.statistics.message_count == 4 * 3000 + 2  # + the run's start and end
    assert {i.compression for i in summary.chunk_indexes} == {"" if compression == "none" else compression}
    if compression != "none":
        assert len(summary.chunk_indexes) > 1  # several chunks, each compressed on its own
    with AnyReader([bag]) as reader:
        via_rosbags = [(c.topic, t, bytes(d)) for c, t, d in reader.messages()]
        qos = {c.topic: c.ext.offered_qos_profiles for c in reader.connections}
    via_stream = []
    with open(file, "rb") as stream:
        channels = {}
        for record in StreamReader(stream).records:
            if type(record).__name__ == "Channel":
                channels[record.id] = record.topic
            elif type(record).__name__ == "Message":
                via_stream.append((channels[record.channel_id], record.log_time, bytes(record.data)))
    via_mcap = [(topic, t, bytes(d)) for topic, t, _, d in mcap_records(bag)]
    assert sorted(via_rosbags) == sorted(via_stream) == sorted(via_mcap)
    assert len(via_rosbags) == 4 * 3000 + 2
    for topic, profiles in qos.items():
        assert len(profiles) == 1, topic
        assert (profiles[0].reliability.name, profiles[0].durability.name, profiles[0].depth) == (
            "RELIABLE",
            "TRANSIENT_LOCAL",
            1000,
        )
    info = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert info["version"] == 9 and info["storage_identifier"] == "mcap"
    assert [t["topic_metadata"]["name"] for t in info["topics_with_message_count"]] == [
        f"/{t}" for t in messages.TOPICS
    ]
    assert all(
        t["topic_metadata"]["type_description_hash"].startswith("RIHS01_")
        for t in info["topics_with_message_count"]
    )


@pytest.mark.slow
def test_compression_makes_bags_smaller_and_reads_the_same(bags_by_compression):
    sizes = {c: next((bags_by_compression / c).glob("*.mcap")).stat().st_size for c in COMPRESSIONS}
    print(f"\n3 s offline bag: {sizes}")
    assert sizes["zstd"] < sizes["lz4"] < sizes["none"]
    columns = [read_bag(bags_by_compression / c).topics for c in COMPRESSIONS]
    for topic in messages.TOPICS:
        for col in columns[0][topic].columns:
            for other in columns[1:]:
                np.testing.assert_array_equal(columns[0][topic][col], other[topic][col])


def test_old_bags_with_relative_topic_names_still_read(tmp_path):
    """Bags written before fully qualified names (rosbags writer, 'measurement')."""
    store = typestore()
    old = tmp_path / "old"
    writer = Writer(old, version=9, storage_plugin=StoragePlugin.MCAP)
    writer.open()
    conns = {t: writer.add_connection(t, ty, typestore=store) for t, ty in messages.TOPICS.items()}
    factory = messages.RosbagsFactory(store)
    scenario = scenario_from_flat({"duration": 0.2})
    for rec in run(scenario):
        stamp = messages.tick_stamp_ns(rec.measurement.tick, 1000.0)
        fields = messages.measurement_fields(rec.measurement, stamp)
        data = store.serialize_cdr(
            factory.make(messages.FRAME_MEASUREMENT, fields), messages.FRAME_MEASUREMENT
        )
        writer.write(conns["measurement"], stamp, data)
    writer.close()
    bag = read_bag(old, topics=["measurement"])
    assert bag.warnings == [] and len(bag.topics["measurement"]) == 200
    assert {r[0] for r in iter_records(old, [])} == {"measurement"}


def test_flush_makes_everything_written_survive_a_crash(tmp_path):
    """After flush(), the file as it is on disk (no summary, as after SIGKILL) holds every message."""
    bag = BagWriter(tmp_path / "crash")
    for i in range(2500):  # a few chunks' worth and a partial one
        fields = messages.measurement_fields(
            type("M", (), {"tick": i, "z1": 0.1, "z2": 0.2, "actuator_force": 1.0})(), i * 1000
        )
        bag.write("measurement", fields, i * 1000)
        if i == 1234:
            bag.flush()
            snapshot = (tmp_path / "crash" / "crash.mcap").read_bytes()
    bag.flush()
    (tmp_path / "copy").mkdir()
    (tmp_path / "copy" / "copy.mcap").write_bytes(snapshot)
    bag.abort()
    for path, n in ((tmp_path / "copy", 1235), (tmp_path / "crash", 2500)):
        warnings: list[str] = []
        ticks = [messages.cdr_tick(d) for *_, d in iter_records(path, warnings)]
        assert ticks == list(range(n)), path
        assert any("metadata.yaml" in w for w in warnings)


# -- damaged bags, through the command-line tools ------------------------------------------------


def run_tool(tool, *args):
    proc = subprocess.run(
        ["ros2", "run", "pac_analysis", tool, *map(str, args)], capture_output=True, text=True, timeout=120
    )
    assert "Traceback" not in proc.stderr, proc.stderr
    return proc


def assert_one_line_problems(proc, tool, minimum=1):
    lines = proc.stderr.strip().splitlines()
    assert len(lines) >= minimum, proc.stderr
    assert all(line.startswith(f"{tool}: ") for line in lines), proc.stderr
    return lines


@pytest.fixture(scope="module")
def good_bag(tmp_path_factory):
    path = tmp_path_factory.mktemp("good") / "good"
    simulate_to_bag(scenario_from_flat({"duration": 6.0}), path, compression="zstd")
    return path


@pytest.mark.parametrize("fraction", [0.0005, 0.4, 0.75, 0.9999])
@pytest.mark.slow
def test_truncated_bag_with_metadata_gives_partial_results_and_exit_1(good_bag, tmp_path, fraction):
    """A truncated bag that still has its metadata.yaml (the old traceback: 'File end magic is
    invalid'): every tool reports one line per problem, what is readable, and exits 1."""
    bag = tmp_path / "cut"
    shutil.copytree(good_bag, bag)
    (file,) = bag.glob("*.mcap")
    data = file.read_bytes()
    file.write_bytes(data[: int(len(data) * fraction)])
    readable = 0
    try:
        readable = len(read_bag(bag).topics.get("plant_truth", []))
    except Exception as exc:  # noqa: BLE001 - only the tools' behaviour is asserted below
        assert fraction < 0.01, exc

    info = run_tool("info", bag)
    assert info.returncode == 1
    lines = assert_one_line_problems(info, "info")
    report = run_tool("report", bag, "--out", tmp_path / "report", "--from", "0.5")
    assert report.returncode == 1
    assert_one_line_problems(report, "report")
    recover = run_tool("recover", bag, "--out", tmp_path / "recovered")
    assert recover.returncode == 1
    assert_one_line_problems(recover, "recover")
    if fraction < 0.01:
        assert lines == [line for line in lines if "no readable message" in line]
        return
    assert 0 < readable <= 6000
    assert re.search(rf"^plant_truth +pac_interfaces/msg/PlantTruth +{readable} ", info.stdout, re.M)
    assert any("truncated" in line for line in lines)
    if readable < 6000:
        assert f"'plant_truth': {readable} of 6000 messages readable" in info.stderr
    runs = json.loads((tmp_path / "report" / "metrics.json").read_text())["runs"]
    assert runs["cut"]["metrics"]["ticks_recorded"] == readable
    recovered = read_bag(tmp_path / "recovered")
    assert recovered.warnings == [] and len(recovered.topics["plant_truth"]) == readable
    again = run_tool("info", tmp_path / "recovered")
    assert again.returncode == 0 and again.stderr == ""


@pytest.mark.slow
def test_truncated_bag_without_metadata_and_missing_topics_via_the_tools(good_bag, tmp_path):
    bag = tmp_path / "crashed"
    shutil.copytree(good_bag, bag)
    (bag / "metadata.yaml").unlink()
    (file,) = bag.glob("*.mcap")
    file.write_bytes(file.read_bytes()[: int(file.stat().st_size * 0.5)])
    for tool in ("info", "report", "recover"):
        args = {"info": (), "report": ("--out", tmp_path / "r"), "recover": ("--out", tmp_path / "rec")}[tool]
        proc = run_tool(tool, bag, *args)
        assert proc.returncode == 1, (tool, proc.stderr)
        lines = assert_one_line_problems(proc, tool, minimum=2)
        assert any("no metadata.yaml" in line for line in lines) and any(
            "truncated" in line for line in lines
        )
    assert "plant_truth" in run_tool("info", tmp_path / "rec").stdout


@pytest.mark.slow
def test_unknown_types_and_empty_bags_via_the_tools(tmp_path):
    store = get_typestore(Stores.ROS2_JAZZY)
    store.register(get_types_from_msg("float64 x", "other_pkg/msg/Thing"))
    foreign = tmp_path / "foreign"
    writer = Writer(foreign, version=9, storage_plugin=StoragePlugin.MCAP)
    writer.open()
    conn = writer.add_connection("/thing", "other_pkg/msg/Thing", typestore=store)
    for i in range(5):
        writer.write(
            conn,
            i,
            store.serialize_cdr(store.types["other_pkg/msg/Thing"](x=float(i)), "other_pkg/msg/Thing"),
        )
    writer.close()
    empty = tmp_path / "empty"
    BagWriter(empty).close()
    for bag, expected in (
        (foreign, "unknown message type other_pkg/msg/Thing"),
        (empty, "no readable message"),
    ):
        for tool in ("info", "report", "recover"):
            proc = run_tool(
                tool, bag, *(("--out", tmp_path / f"{tool}_{bag.name}") if tool != "info" else ())
            )
            assert proc.returncode == 1, (tool, bag, proc.stderr)
            lines = assert_one_line_problems(proc, tool)
            assert any(expected in line or "not a pac topic" in line for line in lines), (tool, lines)


def test_the_offline_publisher_qos_is_what_a_pac_publisher_offers():
    """A bag written offline records its publishers' QoS from plain settings (no rclpy): the same
    entries, in the same order, as rosbag2's record of pac's PUBLISH_QOS profile."""
    from pac_bag.qos import pac_publisher_qos, qos_dict
    from pac_common.qos import PUBLISH_QOS

    (offline,) = pac_publisher_qos()
    assert list(offline.items()) == list(qos_dict(PUBLISH_QOS).items())
