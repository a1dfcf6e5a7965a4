"""Writing pac runs as rosbag2 bags (metadata.yaml version 9 + MCAP).

Bags are written as ``ros2 bag record`` writes them: fully qualified topic names
(``/measurement``), ``ros2msg`` schemas (Foxglove and ``ros2 bag`` decode them), the
publishers' offered QoS profiles, chunked and indexed MCAP (zstd-compressed chunks by
default), and a rosbag2 ``metadata.yaml``.  Messages go in one at a time (``write``,
``write_raw``: the recorder) or as whole runs of columns (``write_many``: the offline
simulator), serialised with numpy in the CDR layout derived from the .msg files
(:mod:`pac_bag.cdr`).
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from pac_common import jsonio
from pac_common.messages import TOPICS, RosbagsFactory

from . import cdr
from .mcap_writer import COMPRESSIONS, McapWriter, message_records
from .names import qualified, topic_key
from .qos import pac_publisher_qos, to_yaml
from .typestore import ensure_type, writer_typestore

#: Chunk compression of new bags: zstd costs the loop nothing measurable (README, bench).
DEFAULT_COMPRESSION = "zstd"


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
    compression, one of ``zstd``, ``lz4``, ``none``.  ``name``: the bag's name, its MCAP file's
    stem (default the directory's name; :func:`atomic_bag` writes under another one).
    """

    def __init__(
        self,
        path: Path | str,
        metadata: Mapping[str, Any] | None = None,
        topics: Mapping[str, str] = TOPICS,
        *,
        compression: str = DEFAULT_COMPRESSION,
        offered_qos: list[dict[str, Any]] | None = None,
        name: str | None = None,
    ) -> None:
        if compression not in COMPRESSIONS:
            raise ValueError(f"compression {compression!r}: allowed {', '.join(COMPRESSIONS)}")
        self.path = Path(path)
        self.path.mkdir(parents=True, exist_ok=False)
        self.store = writer_typestore()
        self.factory = RosbagsFactory(self.store)
        self.compression = compression
        self._file = self.path / f"{name or self.path.name}.mcap"
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
            ensure_type(self.store, typename)
            msgdef, _ = self.store.generate_msgdef(typename, ros_version=2)
            self._schemas[typename] = self._mcap.add_schema(typename, "ros2msg", msgdef.encode())
        channel = self._mcap.add_channel(
            qualified(name),
            self._schemas[typename],
            "cdr",
            {"offered_qos_profiles": to_yaml(qos).strip() if qos else ""},
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

    def write_rows(self, topic: str, rows: Sequence[Mapping[str, Any]], log_times_ns: np.ndarray) -> None:
        """Many messages of one topic as field dictionaries (pac_common.messages), staged as
        ``write_many`` stages them: as columns when the type has a fixed CDR layout, else (a
        sequence: ``pantograph_truth``'s arrays) serialised one by one with rosbags."""
        if not rows:
            return
        try:
            self.write_many(topic, columns_of(rows), log_times_ns)
            return
        except cdr.LayoutError:
            pass
        entry = self._topics[topic]
        times = np.asarray(log_times_ns, dtype=np.int64).reshape(-1)
        blobs = [
            self.store.serialize_cdr(self.factory.make(entry.typename, fields), entry.typename)
            for fields in rows
        ]
        sizes = np.array([len(b) for b in blobs])
        for size in np.unique(sizes):  # message_records takes messages of one size
            mine = np.flatnonzero(sizes == size)
            data = np.frombuffer(b"".join(blobs[i] for i in mine), np.uint8).reshape(mine.size, size)
            records = message_records(entry.channel, times[mine], data)
            self._staged.append((entry.channel, times[mine], records))
        entry.count += len(blobs)

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
        self._custom[f"pac.{key}"] = jsonio.dumps(value)  # strict: a NaN parameter is null

    def close(self) -> None:
        """Write the summary and metadata.yaml: the bag is complete and indexed."""
        if self._staged:
            self._write_staged()
        self._mcap.flush_chunk()
        info = self._metadata()
        self._mcap.add_metadata(
            "rosbag2", {"serialized_metadata": to_yaml(info).strip(), "ROS_DISTRO": "jazzy"}
        )
        self._mcap.close()
        tmp = self.path / "metadata.yaml.tmp"
        tmp.write_text(to_yaml({"rosbag2_bagfile_information": info}))
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


@contextmanager
def atomic_bag(path: Path) -> Iterator[Path]:
    """A temporary directory next to ``path`` to write a bag into (``BagWriter(..., name=path.name)``),
    renamed to ``path`` when the block completes and removed when it raises: a failure (a full
    disk) never leaves a half-written bag under the name asked for."""
    partial = path.with_name(f".{path.name}.partial-{os.getpid()}")
    try:
        yield partial
        os.rename(partial, path)
    except BaseException:
        shutil.rmtree(partial, ignore_errors=True)
        raise


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


def columns_of(rows: Sequence[Mapping[str, Any]], prefix: str = "") -> dict[str, list[Any]]:
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
