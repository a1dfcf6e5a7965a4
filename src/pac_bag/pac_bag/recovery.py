"""Every intact message of a bag, also of one a crash or damage left behind.

Every reader (``read_bag``, ``recover``, ``replay``) goes through :func:`iter_records`: the MCAP
files' data sections record by record (:mod:`pac_bag.mcap_reader`), so a damaged chunk loses
that chunk only, and a bag without summary, index or metadata.yaml reads like a closed one.
Each damage found is one line on the caller's ``warnings``.  A message's type is the one its
MCAP channel's schema names (what the bytes are); where metadata.yaml declares another, that is
said, not followed.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

from .mcap_reader import read_mcap
from .metadata import bag_info, declared_types, lost_messages
from .names import topic_key


def iter_records(path: Path, warnings: list[str]) -> Iterator[tuple[str, str, int, bytes]]:
    """(topic, type, log time [ns], CDR) of every intact message, in file order."""
    files = [path] if path.is_file() else sorted(path.glob("*.mcap"))
    declared: dict[str, str] = {}
    if path.is_dir():
        if (path / "metadata.yaml").is_file():
            bag_info(path, warnings)  # unreadable: said once, here
            declared = declared_types(path)
            lost_messages(path, warnings)
        else:
            warnings.append("no metadata.yaml (the recorder did not close the bag?): read the MCAP files")
    differ: dict[str, str] = {}
    for file in files:
        for record in read_mcap(file, warnings):
            topic = topic_key(record.topic)
            said = declared.get(topic)
            if said is not None and said != record.typename and topic not in differ:
                differ[topic] = (
                    f"topic '{topic}': metadata.yaml declares {said}, the MCAP channel "
                    f"{record.typename}: read as {record.typename}"
                )
            yield topic, record.typename, record.log_time, record.data
    warnings.extend(differ.values())
