"""What a rosbag2 directory's metadata.yaml declares: per-topic types and message counts, and pac's
custom data.  A malformed entry is one line on the caller's ``warnings`` and costs that entry
only, never the others."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from pac_common.files import FileInputError, read_yaml

from .names import topic_key

#: The custom-data key (``pac.lost_messages``) of the messages per topic that DDS reported lost to
#: the recorder: they never reached the bag.
LOST_MESSAGES = "lost_messages"


def bag_info(path: Path, warnings: list[str] | None = None) -> dict[str, Any]:
    """metadata.yaml's ``rosbag2_bagfile_information`` (empty when there is none or it is unreadable,
    which is said on ``warnings`` when given)."""
    file = path / "metadata.yaml"
    if not file.exists():
        return {}
    try:
        # One reading discipline (pac_common.files): a regular file of bounded size, YAML without
        # aliases or duplicate keys; a FIFO or device is refused, never opened.
        info = read_yaml(file, "metadata")["rosbag2_bagfile_information"]
    except FileInputError as exc:
        if warnings is not None:
            warnings.append(f"metadata.yaml unreadable: {exc.problem}: ignored")
        return {}
    except (KeyError, TypeError) as exc:
        if warnings is not None:
            warnings.append(f"metadata.yaml unreadable ({type(exc).__name__}): ignored")
        return {}
    return info if isinstance(info, dict) else {}


def _topic_entries(info: dict[str, Any], warnings: list[str] | None) -> list[tuple[str, dict[str, Any]]]:
    """(topic, entry) of ``topics_with_message_count``; entries without a topic name are reported."""
    entries = info.get("topics_with_message_count") or []
    out = []
    for number, entry in enumerate(entries if isinstance(entries, list) else []):
        try:
            out.append((topic_key(str(entry["topic_metadata"]["name"])), entry))
        except (KeyError, TypeError):
            if warnings is not None:
                warnings.append(f"metadata.yaml: topic entry {number} has no topic name: ignored")
    return out


def declared_counts(path: Path, warnings: list[str] | None = None) -> dict[str, int]:
    """Messages per topic as metadata.yaml declares them (empty without metadata.yaml); a count
    that is not a non-negative integer is said on ``warnings`` and left out."""
    counts: dict[str, int] = {}
    for topic, entry in _topic_entries(bag_info(path), warnings):
        value = entry.get("message_count")
        if isinstance(value, int) and not isinstance(value, bool) and value >= 0:
            counts[topic] = value
        elif warnings is not None:
            warnings.append(
                f"topic '{topic}': metadata.yaml message_count {str(value)[:40]!r} is not a count"
            )
    return counts


def declared_types(path: Path) -> dict[str, str]:
    """Each topic's type as metadata.yaml declares it (empty without metadata.yaml)."""
    types: dict[str, str] = {}
    for topic, entry in _topic_entries(bag_info(path), None):
        metadata = entry.get("topic_metadata")
        if isinstance(metadata, dict) and isinstance(metadata.get("type"), str):
            types[topic] = metadata["type"]
    return types


def read_custom_metadata(path: Path) -> dict[str, Any]:
    """The ``pac.*`` custom data of metadata.yaml (empty when there is none)."""
    try:
        custom = bag_info(path).get("custom_data") or {}
        return {k[4:]: json.loads(v) for k, v in custom.items() if k.startswith("pac.")}
    except (AttributeError, TypeError, ValueError, RecursionError):
        return {}


def lost_messages(path: Path, warnings: list[str]) -> None:
    """Say on ``warnings`` each topic the recorder lost messages of (its ``lost_messages``)."""
    lost = read_custom_metadata(path).get(LOST_MESSAGES)
    if not isinstance(lost, dict):
        return
    for topic, count in sorted(lost.items()):
        if isinstance(count, int) and count > 0:
            warnings.append(f"topic '{topic}': {count} messages lost before they reached the recorder")
