"""Every message of an MCAP file that is still intact, and one line per damage found.

The file is walked record by record through its data section (https://mcap.dev/spec), as the
MCAP CLI's ``recover`` does: no summary, index or footer is needed, so a bag a crash left
behind reads the same as a closed one.  Damage never stops the walk:

- a chunk that cannot be decompressed, or whose records fail the chunk's CRC, is dropped
  whole (a bit flip inside it would otherwise come back as a plausible message: a tick of
  4503599627370642); its message indexes, which follow it, say how many messages of which
  channel were lost, and the problem line says so;
- a record whose header is damaged (its length runs past the end, an unknown opcode, a body
  that does not parse) is skipped up to the next record that parses, and the skipped byte
  range is reported;
- a file cut short ends the walk with one line saying where.

Pure Python (struct, zlib, the zstd and lz4 decompressors); no ROS, no MCAP library: their
readers stop at the first damaged chunk.
"""

from __future__ import annotations

import re
import struct
import zlib
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

from .mcap_writer import (
    MAGIC,
    OP_CHANNEL,
    OP_CHUNK,
    OP_DATA_END,
    OP_FOOTER,
    OP_MESSAGE,
    OP_MESSAGE_INDEX,
    OP_SCHEMA,
)
from .names import topic_key

#: A chunk's uncompressed size above which it is not decompressed (a damaged size field must
#: not allocate gigabytes): 64 times rosbag2's default chunk size of 768 KiB.
MAX_CHUNK_BYTES = 48 << 20
#: The size of a record's header: opcode (1) and body length (8).
RECORD_HEADER = 9
#: Opcodes a reader may meet in a data section (the rest are summary records or reserved).
_KNOWN_OPS = frozenset(range(0x01, 0x10))
#: Where a record could start after damaged bytes: an opcode that can follow a chunk, then a
#: body length below 4 GiB (its upper four bytes zero); each candidate is then parsed.
_RESYNC = re.compile(rb"[\x03\x04\x05\x06\x07\x0f].{4}\x00\x00\x00\x00", re.DOTALL)

_U16, _U32, _U64 = struct.Struct("<H"), struct.Struct("<I"), struct.Struct("<Q")
_CHUNK_HEAD = struct.Struct("<QQQI")
_MESSAGE_HEAD = struct.Struct("<HIQQ")


class McapDamage(ValueError):
    """A record does not parse (used inside this module; callers see problem lines)."""


@dataclass
class McapRecord:
    """One message: its channel's topic and schema name, log time [ns], serialised data."""

    topic: str
    typename: str
    log_time: int
    data: bytes


@dataclass
class _Channel:
    topic: str
    schema_id: int


@dataclass
class _Walk:
    """What the walk of one file has seen so far."""

    buf: memoryview
    name: str
    problems: list[str]
    schemas: dict[int, str] = field(default_factory=dict)
    channels: dict[int, _Channel] = field(default_factory=dict)
    unknown_channel: dict[int, int] = field(default_factory=dict)
    #: The dropped chunk whose message indexes are being counted: (line, messages per channel).
    dropped: tuple[str, dict[int, int]] | None = None

    def typename(self, channel: _Channel) -> str:
        return self.schemas.get(channel.schema_id, "?")

    def close_dropped(self) -> None:
        """Report the chunk dropped last, with what its message indexes say it held."""
        if self.dropped is None:
            return
        line, counts = self.dropped
        self.dropped = None
        if counts:
            per_topic: dict[str, int] = {}
            for channel_id, count in counts.items():
                channel = self.channels.get(channel_id)
                topic = topic_key(channel.topic) if channel else f"channel {channel_id}"
                per_topic[topic] = per_topic.get(topic, 0) + count
            what = ", ".join(f"{t} {n}" for t, n in sorted(per_topic.items()))
            line += f": dropped {sum(counts.values())} messages ({what})"
        else:
            line += ": dropped its messages (no message index follows it to count them)"
        self.problems.append(line)


def _string(buf: memoryview, pos: int, end: int) -> tuple[str, int]:
    if pos + 4 > end:
        raise McapDamage("string length past the record")
    (size,) = _U32.unpack_from(buf, pos)
    pos += 4
    if pos + size > end:
        raise McapDamage("string past the record")
    try:
        return bytes(buf[pos : pos + size]).decode(), pos + size
    except UnicodeDecodeError:
        raise McapDamage("string not UTF-8") from None


def _schema(buf: memoryview, pos: int, end: int) -> tuple[int, str]:
    if pos + 2 > end:
        raise McapDamage("schema record too short")
    (schema_id,) = _U16.unpack_from(buf, pos)
    name, pos = _string(buf, pos + 2, end)
    _, pos = _string(buf, pos, end)  # encoding
    if pos + 4 > end:
        raise McapDamage("schema data length past the record")
    (size,) = _U32.unpack_from(buf, pos)
    if pos + 4 + size != end:
        raise McapDamage("schema data does not fill the record")
    return schema_id, name


def _channel(buf: memoryview, pos: int, end: int) -> tuple[int, _Channel]:
    if pos + 4 > end:
        raise McapDamage("channel record too short")
    channel_id, schema_id = struct.unpack_from("<HH", buf, pos)
    topic, pos = _string(buf, pos + 4, end)
    _, pos = _string(buf, pos, end)  # message encoding
    if pos + 4 > end:
        raise McapDamage("channel metadata length past the record")
    (size,) = _U32.unpack_from(buf, pos)
    if pos + 4 + size != end:
        raise McapDamage("channel metadata does not fill the record")
    return channel_id, _Channel(topic, schema_id)


def _chunk_records(buf: memoryview, pos: int, end: int) -> tuple[int, int, str, memoryview, int, int]:
    """A chunk record's start and end log times, compression, compressed records,
    uncompressed size and CRC."""
    if pos + _CHUNK_HEAD.size > end:
        raise McapDamage("chunk header too short")
    start, stop, size, crc = _CHUNK_HEAD.unpack_from(buf, pos)
    compression, pos = _string(buf, pos + _CHUNK_HEAD.size, end)
    if compression not in ("", "zstd", "lz4"):
        raise McapDamage(f"unknown chunk compression {compression[:16]!r}")
    if pos + 8 > end:
        raise McapDamage("chunk records length past the record")
    (length,) = _U64.unpack_from(buf, pos)
    if pos + 8 + length != end:
        raise McapDamage("chunk records do not fill the record")
    return start, stop, compression, buf[pos + 8 : end], size, crc


def _header_only_chunk_end(buf: memoryview, body: int, end: int) -> int | None:
    """Where a chunk ends whose record length covers its header only (pac's writer before it
    counted the compressed records too): the end its records length gives, when the declared
    length ends exactly at that length field; else None."""
    if end < body + _CHUNK_HEAD.size + 12 or end > len(buf):
        return None
    (size,) = _U32.unpack_from(buf, body + _CHUNK_HEAD.size)
    if body + _CHUNK_HEAD.size + 4 + size + 8 != end:
        return None
    (length,) = _U64.unpack_from(buf, end - 8)
    return end + length if end + length <= len(buf) else None


def _message_index_count(buf: memoryview, pos: int, end: int) -> tuple[int, int]:
    """A message index record's channel id and how many messages it lists."""
    if pos + 6 > end:
        raise McapDamage("message index too short")
    channel_id, size = struct.unpack_from("<HI", buf, pos)
    if pos + 6 + size != end or size % 16:
        raise McapDamage("message index entries do not fill the record")
    return channel_id, size // 16


def _validate(buf: memoryview, op: int, pos: int, end: int) -> None:
    """Parse a record's body enough to trust its length (raises :class:`McapDamage`)."""
    if op == OP_SCHEMA:
        _schema(buf, pos, end)
    elif op == OP_CHANNEL:
        _channel(buf, pos, end)
    elif op == OP_CHUNK:
        _chunk_records(buf, pos, end)
    elif op == OP_MESSAGE_INDEX:
        _message_index_count(buf, pos, end)
    elif op == OP_MESSAGE and end - pos < _MESSAGE_HEAD.size:
        raise McapDamage("message record too short")


def _record_at(buf: memoryview, pos: int) -> tuple[int, int, int] | None:
    """(opcode, body start, body end) of a record at ``pos`` whose body parses, else None."""
    if pos + RECORD_HEADER > len(buf):
        return None
    op = buf[pos]
    (length,) = _U64.unpack_from(buf, pos + 1)
    body, end = pos + RECORD_HEADER, pos + RECORD_HEADER + length
    if op == OP_CHUNK:
        end = _header_only_chunk_end(buf, body, end) or end
    if op not in _KNOWN_OPS or end > len(buf):
        return None
    try:
        _validate(buf, op, body, end)
    except McapDamage:
        return None
    return op, body, end


def _resync(buf: memoryview, pos: int) -> int | None:
    """The next position after ``pos`` where a record starts that parses (None: none does)."""
    for match in _RESYNC.finditer(buf, pos + 1):
        if _record_at(buf, match.start()) is not None:
            return match.start()
    return None


def _decompress(compression: str, data: memoryview, size: int) -> bytes:
    if size > MAX_CHUNK_BYTES:
        raise McapDamage(f"uncompressed size {size} bytes is over the {MAX_CHUNK_BYTES} read")
    try:
        if compression == "zstd":
            import zstandard

            return zstandard.ZstdDecompressor().decompress(data, max_output_size=size)
        if compression == "lz4":
            import lz4.frame

            return lz4.frame.decompress(bytes(data))
    # The decompressors raise their own types on damaged input (zstd: ZstdError, lz4:
    # RuntimeError, both: ValueError on bad frames): all of them mean this chunk is damaged.
    except Exception as exc:  # noqa: BLE001
        raise McapDamage(f"{compression} cannot decompress it ({exc})") from None
    return bytes(data)


def _messages(walk: _Walk, records: memoryview) -> Iterator[McapRecord]:
    """The messages of a chunk's (checked) records; schemas and channels update the walk."""
    pos, end = 0, len(records)
    while pos < end:
        if pos + RECORD_HEADER > end:
            raise McapDamage(f"record header cut at byte {pos} of the chunk")
        op = records[pos]
        (length,) = _U64.unpack_from(records, pos + 1)
        body, stop = pos + RECORD_HEADER, pos + RECORD_HEADER + length
        if stop > end:
            raise McapDamage(f"record at byte {pos} of the chunk runs past it")
        yield from _record(walk, records, op, body, stop)
        pos = stop


def _record(walk: _Walk, buf: memoryview, op: int, body: int, end: int) -> Iterator[McapRecord]:
    """One schema, channel or message record (others are skipped)."""
    if op == OP_SCHEMA:
        schema_id, name = _schema(buf, body, end)
        walk.schemas[schema_id] = name
    elif op == OP_CHANNEL:
        channel_id, new = _channel(buf, body, end)
        walk.channels[channel_id] = new
    elif op == OP_MESSAGE:
        if end - body < _MESSAGE_HEAD.size:
            raise McapDamage("message record too short")
        channel_id, _, log_time, _ = _MESSAGE_HEAD.unpack_from(buf, body)
        known = walk.channels.get(channel_id)
        if known is None:
            walk.unknown_channel[channel_id] = walk.unknown_channel.get(channel_id, 0) + 1
            return
        data = bytes(buf[body + _MESSAGE_HEAD.size : end])
        yield McapRecord(known.topic, walk.typename(known), log_time, data)


def _chunk(walk: _Walk, at: int, body: int, end: int) -> Iterator[McapRecord]:
    start, stop, compression, data, size, crc = _chunk_records(walk.buf, body, end)
    where = f"{walk.name}: chunk at byte {at} (log time {start}..{stop} ns)"
    try:
        records = _decompress(compression, data, size)
        if len(records) != size:
            raise McapDamage(f"{len(records)} bytes decompressed, {size} declared")
        if crc and zlib.crc32(records) != crc:
            raise McapDamage("its records fail the chunk's CRC")
    except McapDamage as exc:
        walk.dropped = (f"{where}: {exc}", {})
        return
    yielded = 0
    try:
        for record in _messages(walk, memoryview(records)):
            yielded += 1
            yield record
    except (McapDamage, struct.error) as exc:  # only without a CRC: keep what came before
        walk.problems.append(f"{where}: {exc}; kept its first {yielded} messages")


def _walk(walk: _Walk) -> Iterator[McapRecord]:
    buf = walk.buf
    pos = len(MAGIC)
    while pos < len(buf):
        if pos + RECORD_HEADER > len(buf):
            walk.close_dropped()
            walk.problems.append(f"{walk.name}: truncated at byte {len(buf)} (in a record header)")
            return
        found = _record_at(buf, pos)
        if found is None:
            resume = _resync(buf, pos)
            op = buf[pos]
            if resume is None:
                walk.close_dropped()
                walk.problems.append(
                    f"{walk.name}: truncated or damaged from byte {pos} to the end (record 0x{op:02x}): "
                    f"{len(buf) - pos} bytes not read"
                )
                return
            walk.close_dropped()
            walk.problems.append(
                f"{walk.name}: damaged record (0x{op:02x}) at byte {pos}: skipped {resume - pos} bytes "
                "to the next readable record"
            )
            pos = resume
            continue
        op, body, end = found
        if op == OP_MESSAGE_INDEX and walk.dropped is not None:
            channel_id, count = _message_index_count(buf, body, end)
            walk.dropped[1][channel_id] = walk.dropped[1].get(channel_id, 0) + count
        else:
            walk.close_dropped()
        if op in (OP_DATA_END, OP_FOOTER):
            # The summary repeats what the data section held: only its presence is checked.
            if bytes(buf[-len(MAGIC) :]) != MAGIC:
                walk.problems.append(
                    f"{walk.name}: truncated after its data section (no closing magic): "
                    "every message read, its summary lost"
                )
            return
        try:
            if op == OP_CHUNK:
                yield from _chunk(walk, pos, body, end)
            else:
                yield from _record(walk, buf, op, body, end)
        except McapDamage as exc:
            walk.problems.append(f"{walk.name}: record 0x{op:02x} at byte {pos}: {exc}; skipped")
        pos = end
    walk.close_dropped()
    walk.problems.append(f"{walk.name}: no data end record (the writer did not close the file)")


def read_mcap(file: Path, problems: list[str]) -> Iterator[McapRecord]:
    """Every intact message of ``file`` in file order; one line per damage on ``problems``.

    ``file`` must be a regular file that starts with the MCAP magic (the caller checks)."""
    data = file.read_bytes()
    if len(data) <= len(MAGIC):
        problems.append(f"{file.name}: nothing after the MCAP magic")
        return
    walk = _Walk(memoryview(data), file.name, problems)
    try:
        yield from _walk(walk)
    finally:
        for channel_id, count in sorted(walk.unknown_channel.items()):
            problems.append(
                f"{file.name}: {count} messages of channel {channel_id}, whose channel record "
                "was not read, skipped"
            )
