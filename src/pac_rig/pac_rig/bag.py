"""rosbag2 (metadata.yaml version 9 + MCAP) writing and reading for pac runs.

Bags are written as ``ros2 bag record`` writes them: fully qualified topic names
(``/measurement``), ``ros2msg`` schemas (Foxglove and ``ros2 bag`` decode them), the
publishers' offered QoS profiles, chunked and indexed MCAP (zstd-compressed chunks by
default), and a rosbag2 ``metadata.yaml``.  Messages go in one at a time (``write``,
``write_raw``: the recorder) or as whole runs of columns (``write_many``: the offline
simulator), serialised with numpy in the CDR layout derived from the .msg files
(:mod:`pac_rig.cdr`).  Reading goes through rosbags for a closed bag and falls back to
the MCAP record stream (a crash leaves no summary, a truncation no footer); old bags with
relative topic names (``measurement``) read the same: :func:`topic_key` is the one place
where names are normalised.
"""

from __future__ import annotations

import json
import os
import struct
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

from pac_common.messages import TOPICS, RosbagsFactory

from . import cdr
from .mcap_writer import COMPRESSIONS, McapWriter, message_records

#: Chunk compression of new bags: zstd costs the loop nothing measurable (README, bench).
DEFAULT_COMPRESSION = "zstd"


def interface_dir() -> Path:
    """pac_interfaces' .msg files (the installed share directory of the package)."""
    from ament_index_python.packages import get_package_share_directory

    return Path(get_package_share_directory("pac_interfaces")) / "msg"


_TYPESTORE: Typestore | None = None


def typestore() -> Typestore:
    """ROS 2 Jazzy types plus pac_interfaces, parsed from the .msg files."""
    global _TYPESTORE
    if _TYPESTORE is None:
        store = get_typestore(Stores.ROS2_JAZZY)
        types: dict = {}
        for msg in sorted(interface_dir().glob("*.msg")):
            types.update(get_types_from_msg(msg.read_text(), f"pac_interfaces/msg/{msg.stem}"))
        store.register(types)
        _TYPESTORE = store
    return _TYPESTORE


def topic_key(name: str) -> str:
    """The name pac uses for a recorded topic: ``/measurement`` (ros2 bag) and ``measurement``
    (bags before the fully qualified names) are both ``measurement``."""
    return name.lstrip("/")


def qualified(topic: str) -> str:
    """The fully qualified name a topic is recorded under, as ``ros2 bag record`` does."""
    return "/" + topic.lstrip("/")


def _duration(value: Any) -> dict[str, int]:
    ns = int(getattr(value, "nanoseconds", value))
    return {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000}


def qos_dict(profile: Any) -> dict[str, Any]:
    """A QoS profile (rclpy ``QoSProfile``, e.g. from ``get_publishers_info_by_topic``) as
    rosbag2 v9 writes it in ``offered_qos_profiles``."""
    return {
        "history": profile.history.name.lower(),
        "depth": int(profile.depth),
        "reliability": profile.reliability.name.lower(),
        "durability": profile.durability.name.lower(),
        "deadline": _duration(profile.deadline),
        "lifespan": _duration(profile.lifespan),
        "liveliness": profile.liveliness.name.lower(),
        "liveliness_lease_duration": _duration(profile.liveliness_lease_duration),
        "avoid_ros_namespace_conventions": bool(profile.avoid_ros_namespace_conventions),
    }


def pac_publisher_qos() -> list[dict[str, Any]]:
    """What every pac publisher offers (pac_common.node.PUBLISH_QOS), for bags written offline."""
    from pac_common.node import PUBLISH_QOS

    return [qos_dict(PUBLISH_QOS)]


def _yaml(value: Any) -> str:
    import yaml

    return yaml.safe_dump(value, default_flow_style=False, sort_keys=False)


@dataclass
class _Topic:
    typename: str
    channel: int
    qos: list[dict[str, Any]]
    digest: str
    count: int = 0


class BagWriter:
    """A rosbag2 directory (MCAP) with the four pac topics (or ``topics``); a context manager.

    ``write`` takes a field dictionary (pac_common.messages) and serialises it with rosbags;
    ``write_raw`` takes CDR bytes as received from DDS; ``write_many`` takes whole columns
    (numpy, vectorised CDR).  ``offered_qos`` (rosbag2 v9 dictionaries, see :func:`qos_dict`)
    defaults to what pac's publishers offer; ``add_topic`` adds a topic later (the recorder
    adds each one when it has seen its publishers).  ``metadata`` goes into the bag's custom
    data (rosbag2 v9) as JSON, so a bag says how it was made.  ``compression``: MCAP chunk
    compression, one of ``zstd``, ``lz4``, ``none``.
    """

    def __init__(
        self,
        path: Path | str,
        metadata: Mapping[str, Any] | None = None,
        topics: Mapping[str, str] = TOPICS,
        *,
        compression: str = DEFAULT_COMPRESSION,
        offered_qos: list[dict[str, Any]] | None = None,
    ) -> None:
        if compression not in COMPRESSIONS:
            raise ValueError(f"compression {compression!r}: allowed {', '.join(COMPRESSIONS)}")
        self.path = Path(path)
        self.path.mkdir(parents=True, exist_ok=False)
        self.store = typestore()
        self.factory = RosbagsFactory(self.store)
        self.compression = compression
        self._file = self.path / f"{self.path.name}.mcap"
        self._mcap = McapWriter(self._file, library="pac (rosbag2 v9)", compression=compression)
        self._topics: dict[str, _Topic] = {}
        self._schemas: dict[str, int] = {}
        self._staged: list[tuple[int, np.ndarray, np.ndarray]] = []
        self._custom: dict[str, str] = {}
        self._layouts: dict[str, cdr.CdrLayout] = {}
        for topic, typename in topics.items():
            self.add_topic(topic, typename, offered_qos)
        for key, value in (metadata or {}).items():
            self.set_metadata(key, value)

    def add_topic(self, topic: str, typename: str, offered_qos: list[dict[str, Any]] | None = None) -> None:
        """Register a topic (relative or fully qualified name) before writing to it."""
        name = topic_key(topic)
        if name in self._topics:
            raise ValueError(f"topic '{name}' is already in the bag")
        qos = pac_publisher_qos() if offered_qos is None else list(offered_qos)
        if typename not in self._schemas:
            msgdef, _ = self.store.generate_msgdef(typename, ros_version=2)
            self._schemas[typename] = self._mcap.add_schema(typename, "ros2msg", msgdef.encode())
        channel = self._mcap.add_channel(
            qualified(name),
            self._schemas[typename],
            "cdr",
            {"offered_qos_profiles": _yaml(qos).strip() if qos else ""},
        )
        self._topics[name] = _Topic(typename, channel, qos, self.store.hash_rihs01(typename))

    @property
    def counts(self) -> dict[str, int]:
        return {name: t.count for name, t in self._topics.items()}

    def write(self, topic: str, fields: Mapping[str, Any], log_time_ns: int) -> None:
        typename = self._topics[topic].typename
        data = self.store.serialize_cdr(self.factory.make(typename, fields), typename)
        self.write_raw(topic, data, log_time_ns)

    def write_raw(self, topic: str, data: bytes | memoryview, log_time_ns: int) -> None:
        if self._staged:
            self._write_staged()
        entry = self._topics[topic]
        self._mcap.add_message(entry.channel, log_time_ns, data)
        entry.count += 1

    def write_many(self, topic: str, columns: Mapping[str, Any], log_times_ns: np.ndarray) -> None:
        """Many messages of one topic: ``columns`` maps each flattened field path
        (``header.stamp.sec``, ``z``, ... as :func:`flatten_fields` gives) to one value per
        message (or one for all).  Messages are staged and go into the file at the next
        ``flush``/``close``/``write_raw``, merged with the other staged topics in log-time
        order (ties: in the order of the ``write_many`` calls), as the recorder would have
        received them."""
        entry = self._topics[topic]
        times = np.asarray(log_times_ns, dtype=np.int64).reshape(-1)
        data = cdr.serialize_many(self.store, entry.typename, columns, times.size)
        self._staged.append((entry.channel, times, message_records(entry.channel, times, data)))
        entry.count += times.size

    def _write_staged(self) -> None:
        staged, self._staged = self._staged, []
        channels, times, sizes, buf = _merge_records(staged)
        self._mcap.add_messages(channels, times, sizes, buf)

    def flush(self) -> None:
        """Close the pending MCAP chunk and push it to the OS: after this, a crash (SIGKILL) of
        the process loses nothing written so far (``recover`` reads it back)."""
        if self._staged:
            self._write_staged()
        self._mcap.flush()

    def set_metadata(self, key: str, value: Any) -> None:
        self._custom[f"pac.{key}"] = json.dumps(value)

    def close(self) -> None:
        """Write the summary and metadata.yaml: the bag is complete and indexed."""
        if self._staged:
            self._write_staged()
        self._mcap.flush_chunk()
        info = self._metadata()
        self._mcap.add_metadata(
            "rosbag2", {"serialized_metadata": _yaml(info).strip(), "ROS_DISTRO": "jazzy"}
        )
        self._mcap.close()
        tmp = self.path / "metadata.yaml.tmp"
        tmp.write_text(_yaml({"rosbag2_bagfile_information": info}))
        os.replace(tmp, self.path / "metadata.yaml")

    def _metadata(self) -> dict[str, Any]:
        start = self._mcap.start_time or 0
        duration = (self._mcap.end_time or 0) - start
        count = sum(t.count for t in self._topics.values())
        return {
            "version": 9,
            "storage_identifier": "mcap",
            "duration": {"nanoseconds": duration},
            "starting_time": {"nanoseconds_since_epoch": start},
            "message_count": count,
            "topics_with_message_count": [
                {
                    "topic_metadata": {
                        "name": qualified(name),
                        "type": t.typename,
                        "serialization_format": "cdr",
                        "offered_qos_profiles": t.qos,
                        "type_description_hash": t.digest,
                    },
                    "message_count": t.count,
                }
                for name, t in self._topics.items()
            ],
            "compression_format": "",  # chunk compression is the storage's own (as rosbag2 does)
            "compression_mode": "",
            "relative_file_paths": [self._file.name],
            "files": [
                {
                    "path": self._file.name,
                    "starting_time": {"nanoseconds_since_epoch": start},
                    "duration": {"nanoseconds": duration},
                    "message_count": count,
                }
            ],
            "custom_data": dict(self._custom),
            "ros_distro": "jazzy",
        }

    def abort(self) -> None:
        """Leave the file as it is (no summary, no metadata.yaml), as a crash would."""
        self._mcap.abort()

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _merge_records(
    staged: list[tuple[int, np.ndarray, np.ndarray]],
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Message records of several topics in one stream ordered by log time (stable: ties in the
    order given): channels, log times, record sizes, records (uint8)."""
    ids = np.array([c for c, _, _ in staged], dtype=np.uint16)
    recsize = np.array([r.shape[1] for _, _, r in staged], dtype=np.int64)
    first = staged[0][1]
    if all(t.shape == first.shape and np.array_equal(t, first) for _, t, _ in staged[1:]):
        # One message of every topic per log time (the offline run): rows side by side.
        n = first.size
        rows = np.concatenate([r for _, _, r in staged], axis=1) if len(staged) > 1 else staged[0][2]
        return np.tile(ids, n), np.repeat(first, len(staged)), np.tile(recsize, n), rows.reshape(-1)
    times = np.concatenate([t for _, t, _ in staged])
    channels = np.concatenate([np.full(t.size, c, dtype=np.uint16) for c, t, _ in staged])
    sizes = np.concatenate([np.full(t.size, r.shape[1], dtype=np.int64) for _, t, r in staged])
    order = np.argsort(times, kind="stable")
    sorted_sizes = sizes[order]
    dest = np.empty_like(sizes)
    dest[order] = np.cumsum(sorted_sizes) - sorted_sizes
    out = np.empty(int(sizes.sum()), dtype=np.uint8)
    begin = 0
    for _, t, records in staged:
        mine = dest[begin : begin + t.size]
        out[mine[:, None] + np.arange(records.shape[1])] = records
        begin += t.size
    return channels[order], times[order], sorted_sizes, out


def flatten_fields(fields: Mapping[str, Any], prefix: str = "") -> Iterator[tuple[str, Any]]:
    """(flattened path, value) of a (nested) field dictionary, as ``write_many`` takes columns."""
    for name, value in fields.items():
        if isinstance(value, Mapping):
            yield from flatten_fields(value, f"{prefix}{name}.")
        else:
            yield f"{prefix}{name}", value


def columns_of(rows: list[Mapping[str, Any]], prefix: str = "") -> dict[str, list[Any]]:
    """Field dictionaries of many messages (all with the same keys) as columns for ``write_many``
    (flattened paths).  One list comprehension per key: a tenth of a generic per-value walk."""
    columns: dict[str, list[Any]] = {}
    for key, value in rows[0].items():
        column = [row[key] for row in rows]
        if isinstance(value, Mapping):
            columns.update(columns_of(column, f"{prefix}{key}."))
        else:
            columns[f"{prefix}{key}"] = column
    return columns


# -- reading ------------------------------------------------------------------------


class BagError(RuntimeError):
    """A bag cannot be read (or only partly); the message is one line."""


@dataclass
class TopicData:
    """All messages of one topic as columns (numpy arrays), plus log times [ns]."""

    typename: str
    log_time_ns: np.ndarray
    columns: dict[str, np.ndarray] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.log_time_ns)

    def __getitem__(self, name: str) -> np.ndarray:
        return self.columns[name]


@dataclass
class BagData:
    path: Path
    topics: dict[str, TopicData]
    metadata: dict[str, Any]
    warnings: list[str]


def _flatten(msg: Any, prefix: str = "") -> Iterator[tuple[str, Any]]:
    for name in msg.__dataclass_fields__:
        value = getattr(msg, name)
        if hasattr(value, "__dataclass_fields__"):
            yield from _flatten(value, f"{prefix}{name}.")
        else:
            yield f"{prefix}{name}", value


def _column(values: list[Any]) -> np.ndarray:
    """One field of every message.  rosbags gives numeric arrays as numpy arrays and sequences of
    messages or strings (``/diagnostics``' ``status``) as lists: those stay one list per message,
    in an object array (numpy cannot stack lists of varying length)."""
    if values and isinstance(values[0], list):
        out = np.empty(len(values), dtype=object)
        out[:] = values
        return out
    return np.array(values)


def _bag_info(path: Path) -> dict[str, Any]:
    """metadata.yaml's ``rosbag2_bagfile_information`` (empty when there is none or it is unreadable)."""
    import yaml

    try:
        info = yaml.safe_load((path / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
        return info if isinstance(info, dict) else {}
    except (OSError, KeyError, TypeError, ValueError, yaml.YAMLError):
        return {}


def read_custom_metadata(path: Path) -> dict[str, Any]:
    """The ``pac.*`` custom data of metadata.yaml (empty when there is none)."""
    try:
        custom = _bag_info(path).get("custom_data") or {}
        return {k[4:]: json.loads(v) for k, v in custom.items() if k.startswith("pac.")}
    except (AttributeError, TypeError, ValueError):
        return {}


def declared_counts(path: Path) -> dict[str, int]:
    """Messages per topic as metadata.yaml declares them (empty without metadata.yaml)."""
    counts: dict[str, int] = {}
    try:
        for entry in _bag_info(path).get("topics_with_message_count") or []:
            counts[topic_key(entry["topic_metadata"]["name"])] = int(entry["message_count"])
    except (KeyError, TypeError, ValueError):
        pass
    return counts


def _rosbags_records(path: Path) -> Iterator[tuple[str, str, int, bytes]]:
    """(topic, type, log time, CDR) of a closed rosbag2 directory, through rosbags."""
    from rosbags.highlevel import AnyReader

    with AnyReader([path], default_typestore=typestore()) as reader:
        for conn, log_time, raw in reader.messages():
            yield topic_key(conn.topic), conn.msgtype, log_time, raw


def _stream_records(files: list[Path], warnings: list[str]) -> Iterator[tuple[str, str, int, bytes]]:
    """The same from the MCAP record stream: works without summary, index or metadata.yaml."""
    from mcap.exceptions import McapError
    from mcap.records import Channel, Message, Schema
    from mcap.stream_reader import StreamReader
    from zstandard import ZstdError

    for file in files:
        schemas: dict[int, str] = {}
        channels: dict[int, tuple[str, str]] = {}
        count = 0
        with open(file, "rb") as stream:
            try:
                for record in StreamReader(stream, skip_magic=False, validate_crcs=False).records:
                    if isinstance(record, Schema):
                        schemas[record.id] = record.name
                    elif isinstance(record, Channel):
                        channels[record.id] = (topic_key(record.topic), schemas.get(record.schema_id, "?"))
                    elif isinstance(record, Message) and record.channel_id in channels:
                        topic, typename = channels[record.channel_id]
                        count += 1
                        yield topic, typename, record.log_time, record.data
            # a damaged chunk: zstd/lz4 (RuntimeError) decompression errors, short reads
            except (McapError, EOFError, ValueError, struct.error, ZstdError, RuntimeError) as exc:
                warnings.append(
                    f"{file.name}: truncated after {count} messages ({type(exc).__name__}); "
                    "kept what was readable"
                )


def iter_records(path: Path, warnings: list[str]) -> Iterator[tuple[str, str, int, bytes]]:
    """(topic, type, log time [ns], CDR) of every message: through rosbags for a closed bag,
    else (no metadata.yaml, or an index rosbags cannot read) from the MCAP record stream."""
    from rosbags.highlevel import AnyReaderError
    from rosbags.rosbag2.errors import ReaderError

    files = [path] if path.is_file() else sorted(path.glob("*.mcap"))
    if path.is_dir() and (path / "metadata.yaml").is_file():
        produced = 0
        try:
            for item in _rosbags_records(path):
                produced += 1
                yield item
            return
        except (AnyReaderError, ReaderError, OSError, ValueError, KeyError, struct.error) as exc:
            if produced:
                warnings.append(f"rosbags stopped after {produced} messages ({exc})")
                return
            warnings.append(f"damaged bag ({exc}): read the MCAP record stream as far as it goes")
    elif path.is_dir():
        warnings.append(
            "no metadata.yaml (the recorder did not close the bag?): read from the MCAP record stream"
        )
    yield from _stream_records(files, warnings)


def read_bag(path: Path | str, topics: Iterable[str] | None = None) -> BagData:
    """Read a pac bag (rosbag2 directory or a bare .mcap) into columns.

    A closed bag is read through rosbags; a bag without metadata.yaml or whose index
    cannot be read (a crashed recorder) is read from the MCAP record stream as far as
    it goes, with a warning.  Unknown message types are skipped with a warning.
    Raises :class:`BagError` (one line) when there is no bag or no readable message.
    Column names flatten nested messages: ``header.stamp.sec``, ``z``, ``theta_hat``.
    """
    path = Path(path)
    wanted = None if topics is None else set(topics)
    if not path.exists():
        raise BagError(f"{path}: no such bag")
    files = [path] if path.is_file() else sorted(path.glob("*.mcap"))
    if not files:
        raise BagError(f"{path}: not a bag (no .mcap file)")
    store = typestore()
    warnings: list[str] = []
    rows: dict[str, list[tuple[int, Any]]] = {}
    typenames: dict[str, str] = {}
    unknown: set[str] = set()

    def consume(records: Iterator[tuple[str, str, int, bytes]]) -> None:
        for topic, typename, log_time, raw in records:
            typenames.setdefault(topic, typename)
            if wanted is not None and topic not in wanted:
                continue
            if typename not in store.types:
                if topic not in unknown:
                    unknown.add(topic)
                    warnings.append(f"topic '{topic}': unknown message type {typename}, skipped")
                continue
            try:
                msg = store.deserialize_cdr(raw, typename)
            except Exception as exc:  # noqa: BLE001 - one corrupt record must not lose the rest
                undecodable.setdefault(topic, [0, f"first at {log_time} ns: {exc}"])[0] += 1
                continue
            rows.setdefault(topic, []).append((log_time, msg))

    undecodable: dict[str, list] = {}
    consume(iter_records(path, warnings))
    for topic, (count, first) in undecodable.items():
        warnings.append(f"topic '{topic}': {count} undecodable messages skipped ({first})")
    if path.is_dir():
        for topic, declared in declared_counts(path).items():
            readable = len(rows.get(topic, ()))
            if readable < declared and (wanted is None or topic in wanted):
                warnings.append(
                    f"topic '{topic}': {readable} of {declared} messages readable (per metadata.yaml)"
                )
    if not rows:
        raise BagError(f"{path}: no readable message" + (f" ({'; '.join(warnings)})" if warnings else ""))
    result: dict[str, TopicData] = {}
    for topic, items in rows.items():
        items.sort(key=lambda item: item[0])
        data = TopicData(typenames[topic], np.array([t for t, _ in items], dtype=np.int64))
        flat = [dict(_flatten(m)) for _, m in items]
        for key in flat[0]:
            data.columns[key] = _column([f[key] for f in flat])
        result[topic] = data
    return BagData(path, result, read_custom_metadata(path) if path.is_dir() else {}, warnings)
