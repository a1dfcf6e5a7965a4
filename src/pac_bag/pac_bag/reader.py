"""Reading pac bags (rosbag2 directories or bare .mcap files) into columns.

Old bags with relative topic names (``measurement``) read the same as new ones
(:func:`pac_bag.names.topic_key`); a damaged bag is read as far as it goes (:mod:`pac_bag.recovery`).
"""

from __future__ import annotations

import stat
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from pac_common.messages import WATCHED_TOPICS

from .metadata import declared_counts, read_custom_metadata
from .recovery import iter_records
from .typestore import typestore


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


#: The first bytes of every MCAP file (the MCAP specification's magic).
MCAP_MAGIC = b"\x89MCAP0\r\n"


def bag_files(path: Path) -> list[Path]:
    """The MCAP files of a bag (a rosbag2 directory or a bare .mcap); :class:`BagError` (one line,
    the same for every tool) when ``path`` is not a bag."""
    if not path.exists():
        raise BagError(f"{path}: no such bag")
    files = [path] if path.is_file() else sorted(path.glob("*.mcap"))
    if not files:
        raise BagError(f"{path}: not a bag (no .mcap file)")
    for file in files:
        try:
            if not stat.S_ISREG(file.stat().st_mode):  # a FIFO would block, a device never end
                raise BagError(f"{path}: not a bag ({file.name} is not a regular file)")
            with open(file, "rb") as handle:
                head = handle.read(len(MCAP_MAGIC))
        except OSError as exc:
            raise BagError(f"{file}: cannot read ({exc.strerror or exc})") from None
        if head != MCAP_MAGIC:
            raise BagError(f"{path}: not a bag ({file.name} is not an MCAP file)")
    return files


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
    bag_files(path)
    store = typestore()
    warnings: list[str] = []
    rows: dict[str, list[tuple[int, Any]]] = {}
    typenames: dict[str, str] = {}
    unknown: set[str] = set()

    def consume(records: Iterator[tuple[str, str, int, bytes]]) -> None:
        for topic, typename, log_time, raw in records:
            if wanted is not None and topic not in wanted:
                continue
            # A topic's columns come from one type: pac's for its own topics, else the first seen;
            # messages of another type on the topic are counted and said.
            if typenames.setdefault(topic, WATCHED_TOPICS.get(topic, typename)) != typename:
                other_types.setdefault(topic, {}).setdefault(typename, 0)
                other_types[topic][typename] += 1
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
    other_types: dict[str, dict[str, int]] = {}
    consume(iter_records(path, warnings))
    for topic, (count, first) in undecodable.items():
        warnings.append(f"topic '{topic}': {count} undecodable messages skipped ({first})")
    for topic, counts in other_types.items():
        others = ", ".join(f"{n} of {t}" for t, n in sorted(counts.items()))
        warnings.append(
            f"topic '{topic}': messages of several types: read {typenames[topic]}, skipped {others}"
        )
    if path.is_dir():
        for topic, declared in declared_counts(path, warnings).items():
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
