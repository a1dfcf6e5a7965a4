"""rosbag2 (metadata.yaml version 9 + MCAP) writing and reading for pac runs.

Writing goes through the rosbags writer with full ``ros2msg`` schemas (Foxglove
and ``ros2 bag`` decode them).  Reading goes through rosbags' MCAP reader, which
also reads a file without a summary section (what a crash leaves behind).
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from pac_common.messages import TOPICS, RosbagsFactory
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

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


def read_bag(path: Path | str, topics: Iterable[str] | None = None) -> BagData:
    """Read a pac bag into columns.  Raises :class:`BagError` when nothing is readable.

    A truncated MCAP (no summary) is read as far as it goes and a warning is added.
    Column names flatten nested messages: ``header.stamp.sec``, ``z``, ``theta_hat``.
    """
    from rosbags.highlevel import AnyReader
    from rosbags.rosbag2.errors import ReaderError

    path = Path(path)
    if not (path / "metadata.yaml").is_file() and not list(path.glob("*.mcap")):
        raise BagError(f"{path}: not a rosbag2 directory (no metadata.yaml, no .mcap)")
    store = typestore()
    warnings: list[str] = []
    rows: dict[str, list[tuple[int, Any]]] = {}
    typenames: dict[str, str] = {}
    try:
        with AnyReader([path], default_typestore=store) as reader:
            wanted = [c for c in reader.connections if topics is None or c.topic.lstrip("/") in topics]
            for conn in reader.connections:
                typenames[conn.topic.lstrip("/")] = conn.msgtype
            try:
                for conn, log_time, raw in reader.messages(connections=wanted):
                    try:
                        msg = reader.deserialize(raw, conn.msgtype)
                    except Exception as exc:  # noqa: BLE001 - a corrupt record must not lose the rest
                        warnings.append(f"{conn.topic}: undecodable message at {log_time} ns ({exc})")
                        continue
                    rows.setdefault(conn.topic.lstrip("/"), []).append((log_time, msg))
            except (ReaderError, OSError, EOFError, ValueError) as exc:
                warnings.append(f"read stopped early: {exc}")
    except (ReaderError, OSError) as exc:
        raise BagError(f"{path}: {exc}") from None
    metadata = read_custom_metadata(path)
    result: dict[str, TopicData] = {}
    for topic, items in rows.items():
        items.sort(key=lambda item: item[0])
        data = TopicData(typenames[topic], np.array([t for t, _ in items], dtype=np.int64))
        flat = [dict(_flatten(m)) for _, m in items]
        for key in flat[0]:
            data.columns[key] = np.array([f[key] for f in flat])
        result[topic] = data
    for topic in typenames:
        if topic not in result and (topics is None or topic in topics):
            result[topic] = TopicData(typenames[topic], np.zeros(0, dtype=np.int64))
    return BagData(path, result, metadata, warnings)
