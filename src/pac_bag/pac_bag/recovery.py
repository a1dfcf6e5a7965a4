"""Every message of a bag, also of one a crash left behind: through rosbags for a closed bag, else
from the MCAP record stream as far as it goes (a crash leaves no summary, a truncation no footer)."""

from __future__ import annotations

import struct
from collections.abc import Iterator
from pathlib import Path

from .names import topic_key
from .typestore import typestore


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
