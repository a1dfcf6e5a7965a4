"""rosbag2 (metadata.yaml version 9 + MCAP) writing and reading for pac runs.

Writing goes through the rosbags writer with full ``ros2msg`` schemas (Foxglove
and ``ros2 bag`` decode them).  Reading goes through rosbags' MCAP reader, which
also reads a file without a summary section (what a crash leaves behind).
"""

from __future__ import annotations

import json
import struct
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

from pac_common.messages import TOPICS, RosbagsFactory

_SOURCE_MSG_DIR = Path(__file__).resolve().parents[2] / "pac_interfaces" / "msg"


def interface_dir() -> Path:
    """Where pac_interfaces' .msg files are: the installed share dir, else the source tree."""
    try:
        from ament_index_python.packages import get_package_share_directory

        installed = Path(get_package_share_directory("pac_interfaces")) / "msg"
        if installed.is_dir():
            return installed
    except (ImportError, LookupError, ValueError):
        pass
    return _SOURCE_MSG_DIR


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


class BagWriter:
    """A rosbag2 directory with the four pac topics; also a context manager.

    ``write`` takes a field dictionary (pac_common.messages) and serialises it;
    ``write_raw`` takes CDR bytes as received from DDS.  ``metadata`` goes into
    the bag's custom data (rosbag2 v9) as JSON, so a bag says how it was made.
    """

    def __init__(
        self,
        path: Path | str,
        metadata: Mapping[str, Any] | None = None,
        topics: Mapping[str, str] = TOPICS,
    ) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.store = typestore()
        self.factory = RosbagsFactory(self.store)
        self._writer = Writer(self.path, version=9, storage_plugin=StoragePlugin.MCAP)
        self._writer.open()
        self._types = dict(topics)
        self._connections = {
            topic: self._writer.add_connection(topic, typename, typestore=self.store)
            for topic, typename in topics.items()
        }
        for key, value in (metadata or {}).items():
            self._writer.set_custom_data(f"pac.{key}", json.dumps(value))
        self.counts = dict.fromkeys(topics, 0)

    def write(self, topic: str, fields: Mapping[str, Any], log_time_ns: int) -> None:
        typename = self._types[topic]
        data = self.store.serialize_cdr(self.factory.make(typename, fields), typename)
        self.write_raw(topic, data, log_time_ns)

    def write_raw(self, topic: str, data: bytes | memoryview, log_time_ns: int) -> None:
        self._writer.write(self._connections[topic], log_time_ns, data)
        self.counts[topic] += 1

    def flush(self) -> None:
        """Close the pending MCAP chunk and push it to the OS: after this, a crash (SIGKILL) of
        the process loses nothing written so far (``recover`` reads it back).

        rosbags writes 1 MiB chunks (about 2.5 s of pac data) and has no public flush; this uses
        its MCAP storage's own chunk closing, so the file stays a valid record stream.
        """
        storage = self._writer.storage
        if storage is not None and hasattr(storage, "close_chunk"):
            if storage.chunk.bio.tell():
                storage.close_chunk()
            storage.bio.flush()

    def set_metadata(self, key: str, value: Any) -> None:
        self._writer.set_custom_data(f"pac.{key}", json.dumps(value))

    def close(self) -> None:
        self._writer.close()

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


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


def read_custom_metadata(path: Path) -> dict[str, Any]:
    """The ``pac.*`` custom data of metadata.yaml (empty when there is none)."""
    import yaml

    try:
        info = yaml.safe_load((path / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
        custom = info.get("custom_data") or {}
        return {k[4:]: json.loads(v) for k, v in custom.items() if k.startswith("pac.")}
    except (OSError, KeyError, TypeError, ValueError, yaml.YAMLError):
        return {}


def _rosbags_records(path: Path) -> Iterator[tuple[str, str, int, bytes]]:
    """(topic, type, log time, CDR) of a closed rosbag2 directory, through rosbags."""
    from rosbags.highlevel import AnyReader

    with AnyReader([path], default_typestore=typestore()) as reader:
        for conn, log_time, raw in reader.messages():
            yield conn.topic.lstrip("/"), conn.msgtype, log_time, raw


def _stream_records(files: list[Path], warnings: list[str]) -> Iterator[tuple[str, str, int, bytes]]:
    """The same from the MCAP record stream: works without summary, index or metadata.yaml."""
    from mcap.exceptions import McapError
    from mcap.records import Channel, Message, Schema
    from mcap.stream_reader import StreamReader

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
                        channels[record.id] = (record.topic.lstrip("/"), schemas.get(record.schema_id, "?"))
                    elif isinstance(record, Message) and record.channel_id in channels:
                        topic, typename = channels[record.channel_id]
                        count += 1
                        yield topic, typename, record.log_time, record.data
            except (McapError, EOFError, ValueError, struct.error) as exc:
                warnings.append(
                    f"{file.name}: truncated after {count} messages ({type(exc).__name__}); "
                    "kept what was readable"
                )


def iter_records(path: Path, warnings: list[str]) -> Iterator[tuple[str, str, int, bytes]]:
    """(topic, type, log time [ns], CDR) of every message: through rosbags for a closed bag,
    else (no metadata.yaml, or an index rosbags cannot read) from the MCAP record stream."""
    from rosbags.rosbag2.errors import ReaderError

    files = [path] if path.is_file() else sorted(path.glob("*.mcap"))
    if path.is_dir() and (path / "metadata.yaml").is_file():
        produced = 0
        try:
            for item in _rosbags_records(path):
                produced += 1
                yield item
            return
        except (ReaderError, OSError, ValueError, KeyError) as exc:
            if produced:
                warnings.append(f"rosbags stopped after {produced} messages ({exc})")
                return
            warnings.append(f"rosbags could not read the bag ({exc}); read the MCAP record stream instead")
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
                warnings.append(f"{topic}: undecodable message at {log_time} ns ({exc})")
                continue
            rows.setdefault(topic, []).append((log_time, msg))

    consume(iter_records(path, warnings))
    if not rows:
        raise BagError(f"{path}: no readable message" + (f" ({'; '.join(warnings)})" if warnings else ""))
    result: dict[str, TopicData] = {}
    for topic, items in rows.items():
        items.sort(key=lambda item: item[0])
        data = TopicData(typenames[topic], np.array([t for t, _ in items], dtype=np.int64))
        flat = [dict(_flatten(m)) for _, m in items]
        for key in flat[0]:
            data.columns[key] = np.array([f[key] for f in flat])
        result[topic] = data
    return BagData(path, result, read_custom_metadata(path) if path.is_dir() else {}, warnings)
