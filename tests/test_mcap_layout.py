"""pac's MCAP writer against the MCAP specification (https://mcap.dev/spec), record by record.

The readers pac and its users run (rosbags, the mcap library's, pac's own) only need part of a
file: a reader that scans the chunks never looks at the summary, one that seeks by the summary
never checks it against the chunks. So every record the writer makes is checked here against the
records it describes, with the mcap library decoding each record at the offset a walk of the file
finds it: chunk indexes against the chunks (offset, lengths, times, compression) and their
message indexes (every message exactly once, at its offset), statistics against the messages,
the summary offsets against the summary's groups, the footer against both, and CRCs checked by
the library where the writer states one.
"""

from __future__ import annotations

import io
import struct
import zlib
from collections import Counter
from pathlib import Path

import lz4.frame
import numpy as np
import pytest
import zstandard
from mcap import records as mr
from mcap.reader import make_reader
from mcap.stream_reader import StreamReader

from pac_bag.mcap_writer import CHUNK_SIZE, MAGIC, McapWriter, message_records

pytestmark = pytest.mark.unit

#: Bytes of a record's opcode and length.
RECORD_HEADER = 9


def walk(data: bytes, start: int, end: int) -> list[tuple[int, int, int]]:
    """(offset, opcode, record size with its header) of every record in data[start:end]."""
    out = []
    offset = start
    while offset < end:
        op, length = struct.unpack_from("<BQ", data, offset)
        out.append((offset, op, RECORD_HEADER + length))
        offset += RECORD_HEADER + length
    assert offset == end, "the records do not end where the section does"
    return out


def record_at(data: bytes, offset: int) -> mr.McapRecord:
    """The record at ``offset``, decoded by the mcap library (chunks left compressed)."""
    return next(StreamReader(io.BytesIO(data[offset:]), skip_magic=True, emit_chunks=True).records)


def decompress(chunk: mr.Chunk) -> bytes:
    return {
        "": lambda b: b,
        "zstd": lambda b: zstandard.ZstdDecompressor().decompress(b, max_output_size=chunk.uncompressed_size),
        "lz4": lz4.frame.decompress,
    }[chunk.compression](chunk.data)


def messages_in(chunk_data: bytes) -> list[tuple[int, int, int, int]]:
    """(offset in the chunk, channel, sequence, log time) of every message record of a chunk."""
    out = []
    for offset, op, _ in walk(chunk_data, 0, len(chunk_data)):
        assert op == mr.Opcode.MESSAGE
        message = record_at(chunk_data, offset)
        assert isinstance(message, mr.Message) and message.publish_time == message.log_time
        out.append((offset, message.channel_id, message.sequence, message.log_time))
    return out


def write_bag(path: Path, compression: str, messages: int) -> dict[int, list[int]]:
    """A bag of two channels, written one message at a time and as arrays, its log times not in
    order (a chunk's start and end times are then its min and max, not its first and last). Big
    enough for several chunks. Returns every channel's log times as written."""
    writer = McapWriter(path, compression=compression)
    schema = writer.add_schema("pac/Test", "ros2msg", b"float64 x")
    one = writer.add_channel("/one", schema, "cdr", {"offered_qos_profiles": ""})
    many = writer.add_channel("/many", schema, "cdr", {})
    times: dict[int, list[int]] = {one: [], many: []}
    rng = np.random.default_rng(7)
    for k in range(messages):
        t = int(1_000_000 * (messages - k))  # descending
        writer.add_message(one, t, bytes(rng.integers(0, 256, 300, dtype=np.uint8)))
        times[one].append(t)
    for block in range(3):
        log_times = (np.arange(messages, dtype=np.uint64) * 997 + 10**9 + block) % (5 * 10**9)
        data = rng.integers(0, 256, (messages, 1000), dtype=np.uint8)
        records = message_records(many, log_times, data)
        sizes = np.full(messages, records.shape[1])
        writer.add_messages(np.full(messages, many, dtype=np.uint16), log_times, sizes, records)
        times[many] += log_times.tolist()
    single = message_records(many, np.array([3], dtype=np.uint64), np.zeros((1, 1000), dtype=np.uint8))
    writer.add_messages(
        np.array([many], dtype=np.uint16), np.array([3], dtype=np.uint64), [single.shape[1]], single
    )
    times[many].append(3)  # a call with one record
    writer.add_metadata("rosbag2", {"serialized_bag_info": "x"})
    writer.close()
    return times


@pytest.fixture(scope="module", params=["zstd", "lz4", "none"])
def bag(request, tmp_path_factory) -> tuple[bytes, dict[int, list[int]]]:
    path = tmp_path_factory.mktemp("mcap") / "bag.mcap"
    times = write_bag(path, request.param, 1500)
    return path.read_bytes(), times


def sections(data: bytes) -> tuple[list[tuple[int, int, int]], mr.Footer]:
    """Every record of the file (after the leading magic, before the footer) and the footer."""
    assert data[:8] == MAGIC and data[-8:] == MAGIC
    footer_offset = len(data) - 8 - (RECORD_HEADER + 20)
    footer = record_at(data, footer_offset)
    assert isinstance(footer, mr.Footer)
    return walk(data, 8, footer_offset), footer


def test_the_chunks_hold_every_message_once_each_indexed_at_its_offset(bag):
    data, times = bag
    records, _ = sections(data)
    seen: dict[int, list[int]] = {cid: [] for cid in times}
    chunks = [(offset, size) for offset, op, size in records if op == mr.Opcode.CHUNK]
    assert len(chunks) >= 3
    for i, (offset, op, _) in enumerate(records):
        if op != mr.Opcode.CHUNK:
            continue
        chunk = record_at(data, offset)
        assert isinstance(chunk, mr.Chunk)
        body = decompress(chunk)
        assert len(body) == chunk.uncompressed_size and zlib.crc32(body) == chunk.uncompressed_crc
        # closed once it reaches CHUNK_SIZE: the record that reached it is the last one
        assert len(body) < CHUNK_SIZE + 31 + 1000
        if offset != chunks[-1][0]:
            assert len(body) >= CHUNK_SIZE
        inside = messages_in(body)
        assert chunk.message_start_time == min(t for *_, t in inside)
        assert chunk.message_end_time == max(t for *_, t in inside)
        assert {seq for _, _, seq, _ in inside} == {0}  # as rosbags writes them
        # the message indexes follow the chunk: one per channel in it, listing exactly its messages
        indexed = []
        j = i + 1
        while j < len(records) and records[j][1] == mr.Opcode.MESSAGE_INDEX:
            index = record_at(data, records[j][0])
            assert isinstance(index, mr.MessageIndex)
            indexed += [(o, index.channel_id, t) for t, o in index.records]
            j += 1
        assert sorted(indexed) == sorted((o, cid, t) for o, cid, _, t in inside)
        assert len({cid for _, cid, _ in indexed}) == j - i - 1  # one index per channel
        for _, cid, _, t in inside:
            seen[cid].append(t)
    for cid, written in times.items():
        assert sorted(seen[cid]) == sorted(written), cid


def test_the_summary_describes_the_data_section(bag):
    data, times = bag
    records, footer = sections(data)
    ops = [op for _, op, _ in records]
    data_end = ops.index(mr.Opcode.DATA_END)
    assert record_at(data, records[data_end][0]).data_section_crc == 0  # not computed, and said so
    offsets = {op: [r for r in records if r[1] == op] for op in set(ops)}
    # the footer points at the summary's first record and at the first summary offset
    summary = [r for r in records if r[0] >= footer.summary_start]
    assert summary[0][0] == footer.summary_start and records[data_end][0] < footer.summary_start
    assert footer.summary_crc == 0
    first_offset = offsets[mr.Opcode.SUMMARY_OFFSET][0][0]
    assert footer.summary_offset_start == first_offset
    # each summary offset names one group of the summary, all of its records and nothing more
    groups = {}
    for offset, _, _ in offsets[mr.Opcode.SUMMARY_OFFSET]:
        group = record_at(data, offset)
        members = [r for r in summary if r[0] < first_offset and r[1] == group.group_opcode]
        assert group.group_start == members[0][0]
        assert group.group_length == sum(size for _, _, size in members)
        assert group.group_start + group.group_length == members[-1][0] + members[-1][2]
        groups[group.group_opcode] = len(members)
    summary_ops = Counter(op for _, op, _ in summary if op != mr.Opcode.SUMMARY_OFFSET)
    assert groups == dict(summary_ops)
    # chunk indexes: one per chunk, in order, each the chunk's offset, lengths, times and indexes
    chunk_indexes = [record_at(data, o) for o, op, _ in summary if op == mr.Opcode.CHUNK_INDEX]
    chunks = [r for r in records if r[1] == mr.Opcode.CHUNK]
    assert len(chunk_indexes) == len(chunks)
    for ci, (offset, _, size) in zip(chunk_indexes, chunks, strict=True):
        chunk = record_at(data, offset)
        assert (ci.chunk_start_offset, ci.chunk_length) == (offset, size)
        assert (ci.message_start_time, ci.message_end_time) == (
            chunk.message_start_time,
            chunk.message_end_time,
        )
        assert (ci.compression, ci.compressed_size) == (chunk.compression, len(chunk.data))
        assert ci.uncompressed_size == chunk.uncompressed_size
        following = [r for r in records if r[0] >= offset + size]
        indexes = []
        for r in following:
            if r[1] != mr.Opcode.MESSAGE_INDEX:
                break
            indexes.append(r)
        assert ci.message_index_offsets == {record_at(data, o).channel_id: o for o, _, _ in indexes}
        assert ci.message_index_length == sum(s for _, _, s in indexes)
    # statistics: what the data section holds
    (stats,) = [record_at(data, o) for o, op, _ in summary if op == mr.Opcode.STATISTICS]
    every = [t for ts in times.values() for t in ts]
    assert stats.message_count == len(every)
    assert stats.channel_message_counts == {cid: len(ts) for cid, ts in times.items()}
    assert (stats.message_start_time, stats.message_end_time) == (min(every), max(every))
    assert (stats.schema_count, stats.channel_count) == (1, 2)
    assert (stats.chunk_count, stats.metadata_count, stats.attachment_count) == (len(chunks), 1, 0)
    # the metadata index points at the metadata record
    (metadata_index,) = [record_at(data, o) for o, op, _ in summary if op == mr.Opcode.METADATA_INDEX]
    (metadata,) = offsets[mr.Opcode.METADATA]
    assert (metadata_index.offset, metadata_index.length) == (metadata[0], metadata[2])
    assert metadata_index.name == record_at(data, metadata[0]).name == "rosbag2"


def test_a_reader_that_seeks_by_the_summary_finds_every_message(bag):
    data, times = bag
    reader = make_reader(io.BytesIO(data), validate_crcs=True)
    got = Counter(message.channel_id for _, _, message in reader.iter_messages(log_time_order=False))
    assert got == Counter({cid: len(ts) for cid, ts in times.items()})
    summary = reader.get_summary()
    assert summary is not None and summary.statistics.message_count == sum(got.values())


def test_an_empty_bag_has_a_summary_of_nothing(tmp_path):
    writer = McapWriter(tmp_path / "empty.mcap", compression="none")
    writer.add_channel("/none", writer.add_schema("pac/Test", "ros2msg", b""), "cdr", {})
    writer.close()
    data = (tmp_path / "empty.mcap").read_bytes()
    records, footer = sections(data)
    assert not [r for r in records if r[1] in (mr.Opcode.CHUNK, mr.Opcode.CHUNK_INDEX)]
    (stats,) = [record_at(data, o) for o, op, _ in records if op == mr.Opcode.STATISTICS]
    assert (stats.message_count, stats.message_start_time, stats.message_end_time) == (0, 0, 0)
    assert stats.channel_message_counts == {1: 0} and stats.chunk_count == 0


@pytest.mark.parametrize("as_arrays", [False, True], ids=["one_by_one", "arrays"])
def test_a_chunk_closes_when_it_reaches_chunk_size_exactly(tmp_path, as_arrays):
    """Records adding up to CHUNK_SIZE bytes exactly fill a chunk: the next record opens another."""
    writer = McapWriter(tmp_path / "edge.mcap", compression="none")
    channel = writer.add_channel("/edge", writer.add_schema("pac/Test", "ros2msg", b""), "cdr", {})
    size = CHUNK_SIZE // 4  # four records of this size fill a chunk
    if as_arrays:
        records = message_records(channel, np.arange(5, dtype=np.uint64), np.zeros((5, size - 31), np.uint8))
        writer.add_messages(
            np.full(5, channel, dtype=np.uint16), np.arange(5, dtype=np.uint64), [size] * 5, records
        )
    else:
        for k in range(5):
            writer.add_message(channel, k, bytes(size - 31))
    writer.close()
    data = (tmp_path / "edge.mcap").read_bytes()
    records_, _ = sections(data)
    chunks = [record_at(data, o) for o, op, _ in records_ if op == mr.Opcode.CHUNK]
    assert [c.uncompressed_size for c in chunks] == [CHUNK_SIZE, size]
