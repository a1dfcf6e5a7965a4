"""A chunked, indexed MCAP writer that takes messages one at a time or as whole arrays.

Record layout per the MCAP specification (https://mcap.dev/spec): header, schemas and
channels in the data section (outside chunks, so a reader of a damaged file still finds
them before the chunks that use them), chunks (optionally zstd or lz4 compressed, with the
CRC of their records) each followed by its message indexes, then data end, the summary
(schemas, channels, chunk indexes, metadata index, statistics), summary offsets and the
footer.  This is the layout ``ros2 bag record`` (rosbag2_storage_mcap) writes.

Messages are staged in a pending chunk; ``flush`` closes it and hands it to the OS, so a
process killed afterwards loses nothing written before (the record stream stays valid).
Whole arrays of equal-size messages go in without a Python loop per message
(``add_messages``).  Pure Python + numpy, no ROS.
"""

from __future__ import annotations

import struct
import zlib
from collections.abc import Mapping
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np

MAGIC = b"\x89MCAP0\r\n"
OP_HEADER, OP_FOOTER, OP_SCHEMA, OP_CHANNEL, OP_MESSAGE, OP_CHUNK = 0x01, 0x02, 0x03, 0x04, 0x05, 0x06
OP_MESSAGE_INDEX, OP_CHUNK_INDEX, OP_STATISTICS, OP_METADATA = 0x07, 0x08, 0x0B, 0x0C
OP_METADATA_INDEX, OP_SUMMARY_OFFSET, OP_DATA_END = 0x0D, 0x0E, 0x0F

COMPRESSIONS = ("zstd", "lz4", "none")
#: Uncompressed chunk size at which a chunk is closed [bytes] (rosbag2's MCAP default is 768 KiB).
CHUNK_SIZE = 1 << 20

#: opcode, record length, channel id, sequence, log time, publish time: then the data.
MESSAGE_HEADER = np.dtype(
    [
        ("op", "u1"),
        ("length", "<u8"),
        ("channel", "<u2"),
        ("sequence", "<u4"),
        ("log_time", "<u8"),
        ("publish_time", "<u8"),
    ]
)
_MESSAGE_HEADER = struct.Struct("<BQHIQQ")
assert _MESSAGE_HEADER.size == MESSAGE_HEADER.itemsize == 31


def _string(value: str) -> bytes:
    raw = value.encode()
    return struct.pack("<I", len(raw)) + raw


def _map(items: Mapping[str, str]) -> bytes:
    body = b"".join(_string(k) + _string(v) for k, v in items.items())
    return struct.pack("<I", len(body)) + body


def _record(op: int, body: bytes) -> bytes:
    return struct.pack("<BQ", op, len(body)) + body


def compressor(name: str):
    """bytes -> compressed bytes for an MCAP chunk compression name (``none``: identity)."""
    if name == "zstd":
        import zstandard

        return zstandard.ZstdCompressor(level=1).compress  # level 1: what zstd_fast presets use
    if name == "lz4":
        import lz4.frame

        return lz4.frame.compress
    if name == "none":
        return lambda data: data
    raise ValueError(f"compression {name!r}: allowed {', '.join(COMPRESSIONS)}")


class McapWriter:
    """Write an MCAP file; ``close`` writes the summary and footer."""

    def __init__(
        self, path: Path | str, *, profile: str = "ros2", library: str = "pac", compression: str = "zstd"
    ) -> None:
        self._compress = compressor(compression)  # before opening: a bad name creates no file
        self.compression = "" if compression == "none" else compression
        self.path = Path(path)
        self._file: BinaryIO = self.path.open("xb")
        self._file.write(MAGIC + _record(OP_HEADER, _string(profile) + _string(library)))
        self._schemas: list[bytes] = []
        self._channels: list[bytes] = []
        self._chunk_indexes: list[bytes] = []
        self._metadata: list[tuple[str, dict[str, str]]] = []
        self.channel_counts: dict[int, int] = {}
        self.start_time: int | None = None
        self.end_time: int | None = None
        self._new_chunk()

    # -- schemas and channels ---------------------------------------------------------

    def add_schema(self, name: str, encoding: str, data: bytes) -> int:
        schema_id = len(self._schemas) + 1
        body = struct.pack("<H", schema_id) + _string(name) + _string(encoding)
        body += struct.pack("<I", len(data)) + data
        self._schemas.append(_record(OP_SCHEMA, body))
        self._file.write(self._schemas[-1])
        return schema_id

    def add_channel(self, topic: str, schema_id: int, encoding: str, metadata: Mapping[str, str]) -> int:
        channel_id = len(self._channels) + 1
        body = struct.pack("<HH", channel_id, schema_id) + _string(topic) + _string(encoding)
        self._channels.append(_record(OP_CHANNEL, body + _map(metadata)))
        self._file.write(self._channels[-1])
        self.channel_counts[channel_id] = 0
        return channel_id

    def add_metadata(self, name: str, values: Mapping[str, str]) -> None:
        self._metadata.append((name, dict(values)))

    # -- messages -------------------------------------------------------------------------

    def _new_chunk(self) -> None:
        self._parts: list[Any] = []  # bytes, memoryviews, uint8 arrays: any buffer bytes.join takes
        self._size = 0
        # per part: channel ids, log times, offsets of the records in the chunk
        self._index: list[tuple[np.ndarray | int, np.ndarray | int, np.ndarray | int]] = []
        self._chunk_start: int | None = None
        self._chunk_end: int | None = None

    def _times(self, first: int, last: int) -> None:
        self._chunk_start = first if self._chunk_start is None else min(self._chunk_start, first)
        self._chunk_end = last if self._chunk_end is None else max(self._chunk_end, last)

    def add_message(self, channel_id: int, log_time: int, data: bytes | memoryview) -> None:
        """One message (publish time = log time, sequence 0, as rosbags writes them)."""
        record = _MESSAGE_HEADER.pack(OP_MESSAGE, 22 + len(data), channel_id, 0, log_time, log_time)
        self._index.append((channel_id, log_time, self._size))
        self._parts.append(record)
        self._parts.append(data)
        self._size += 31 + len(data)
        self._times(log_time, log_time)
        self.channel_counts[channel_id] += 1
        if self._size >= CHUNK_SIZE:
            self.flush_chunk()

    def add_messages(
        self, channels: np.ndarray, log_times: np.ndarray, sizes: np.ndarray, records: np.ndarray
    ) -> None:
        """Many message records at once, in the order given (may interleave channels).

        ``records``: uint8 array of complete message records (see :func:`message_records`) one
        after the other; ``channels``, ``log_times``, ``sizes`` (record sizes in bytes): one
        entry per record."""
        n = len(log_times)
        if n == 0:
            return
        buf = np.ascontiguousarray(records, dtype=np.uint8).reshape(-1)
        lengths = np.asarray(sizes, dtype=np.int64)
        if int(lengths.sum()) != buf.size:
            raise ValueError(f"record sizes add up to {int(lengths.sum())} bytes, records have {buf.size}")
        ends = np.cumsum(lengths)
        starts = ends - lengths
        first = 0
        while first < n:
            room = CHUNK_SIZE - self._size
            # records that start within the room left in this chunk (at least one)
            last = max(first + 1, int(np.searchsorted(ends, starts[first] + room, side="right")))
            lo, hi = int(starts[first]), int(ends[last - 1])
            self._parts.append(buf[lo:hi])
            self._index.append(
                (channels[first:last], log_times[first:last], starts[first:last] - lo + self._size)
            )
            self._size += hi - lo
            self._times(int(log_times[first:last].min()), int(log_times[first:last].max()))
            ids, counts = np.unique(channels[first:last], return_counts=True)
            for cid, count in zip(ids.tolist(), counts.tolist(), strict=True):
                self.channel_counts[cid] += count
            first = last
            if self._size >= CHUNK_SIZE:
                self.flush_chunk()

    def flush_chunk(self) -> None:
        """Write the pending chunk (with its message indexes) to the file, if it has messages."""
        if not self._size:
            return
        data = b"".join(self._parts)
        compressed = self._compress(data)
        assert self._chunk_start is not None and self._chunk_end is not None  # set with the first message
        start, end = self._chunk_start, self._chunk_end
        body = struct.pack("<QQQI", start, end, len(data), zlib.crc32(data))
        body += _string(self.compression) + struct.pack("<Q", len(compressed))
        chunk_offset = self._file.tell()
        # The record's length covers its whole body, the compressed records included (pac before
        # this wrote the header's length only: readers that walk records by their length, as
        # a recovery must, took every chunk for damage; pac_bag.mcap_reader reads both).
        self._file.write(struct.pack("<BQ", OP_CHUNK, len(body) + len(compressed)) + body)
        self._file.write(compressed)
        index_start = self._file.tell()
        offsets = self._message_indexes(index_start)
        index_end = self._file.tell()
        index = struct.pack("<QQQQ", start, end, chunk_offset, index_start - chunk_offset)
        index += struct.pack("<I", 10 * len(offsets))
        index += b"".join(struct.pack("<HQ", cid, off) for cid, off in offsets)
        index += struct.pack("<Q", index_end - index_start) + _string(self.compression)
        index += struct.pack("<QQ", len(compressed), len(data))
        self._chunk_indexes.append(_record(OP_CHUNK_INDEX, index))
        self.start_time = start if self.start_time is None else min(self.start_time, start)
        self.end_time = end if self.end_time is None else max(self.end_time, end)
        self._new_chunk()

    def _message_indexes(self, position: int) -> list[tuple[int, int]]:
        channels = np.concatenate([np.atleast_1d(np.asarray(c, dtype=np.uint16)) for c, _, _ in self._index])
        times = np.concatenate([np.atleast_1d(np.asarray(t, dtype=np.uint64)) for _, t, _ in self._index])
        offs = np.concatenate([np.atleast_1d(np.asarray(o, dtype=np.uint64)) for _, _, o in self._index])
        out = []
        for cid in np.unique(channels).tolist():
            mine = channels == cid
            pairs = np.empty((int(mine.sum()), 2), dtype="<u8")
            pairs[:, 0], pairs[:, 1] = times[mine], offs[mine]
            body = struct.pack("<HI", cid, pairs.nbytes) + pairs.tobytes()
            out.append((cid, position))
            position += self._file.write(_record(OP_MESSAGE_INDEX, body))
        return out

    def flush(self) -> None:
        """Close the pending chunk and push the file to the OS (survives a SIGKILL from here)."""
        self.flush_chunk()
        self._file.flush()

    # -- closing ----------------------------------------------------------------------------

    def close(self) -> None:
        self.flush_chunk()
        f = self._file
        f.write(_record(OP_DATA_END, struct.pack("<I", 0)))
        metadata_index = b""
        for name, values in self._metadata:
            offset = f.tell()
            length = f.write(_record(OP_METADATA, _string(name) + _map(values)))
            metadata_index += _record(OP_METADATA_INDEX, struct.pack("<QQ", offset, length) + _string(name))
        summary_start = f.tell()
        groups = []
        for op, records in (
            (OP_SCHEMA, self._schemas),
            (OP_CHANNEL, self._channels),
            (OP_CHUNK_INDEX, self._chunk_indexes),
            (OP_METADATA_INDEX, [metadata_index] if metadata_index else []),
        ):
            if records:
                start = f.tell()
                f.write(b"".join(records))
                groups.append((op, start, f.tell() - start))
        counts = b"".join(struct.pack("<HQ", c, n) for c, n in sorted(self.channel_counts.items()))
        stats = struct.pack(
            "<QHIIIIQQI",
            sum(self.channel_counts.values()),
            len(self._schemas),
            len(self._channels),
            0,
            len(self._metadata),
            len(self._chunk_indexes),
            self.start_time or 0,
            self.end_time or 0,
            len(counts),
        )
        start = f.tell()
        f.write(_record(OP_STATISTICS, stats + counts))
        groups.append((OP_STATISTICS, start, f.tell() - start))
        summary_offset_start = f.tell()
        for op, start, length in groups:
            f.write(_record(OP_SUMMARY_OFFSET, struct.pack("<BQQ", op, start, length)))
        f.write(_record(OP_FOOTER, struct.pack("<QQI", summary_start, summary_offset_start, 0)))
        f.write(MAGIC)
        f.close()

    def abort(self) -> None:
        """Close the file as it is (no summary): what a crash leaves, readable as a record stream."""
        self._file.close()


def message_records(channel_id: int, log_times: np.ndarray, data: np.ndarray) -> np.ndarray:
    """Complete MCAP message records for ``n`` equal-size messages: uint8 array (n, 31 + size).

    ``data``: uint8 array (n, size), e.g. from :func:`pac_bag.cdr.serialize_many`."""
    n, size = data.shape
    dtype = np.dtype(MESSAGE_HEADER.descr + [("data", "u1", (size,))])
    out = np.empty(n, dtype=dtype)
    out["op"] = OP_MESSAGE
    out["length"] = 22 + size
    out["channel"] = channel_id
    out["sequence"] = 0
    out["log_time"] = log_times
    out["publish_time"] = log_times
    out["data"] = data
    return out.view(np.uint8).reshape(n, dtype.itemsize)
