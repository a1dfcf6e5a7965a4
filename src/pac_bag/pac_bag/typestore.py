"""The rosbags type store of pac bags: ROS 2 Jazzy's types plus pac_interfaces, parsed from the .msg files."""

from __future__ import annotations

from pathlib import Path

from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore


def interface_dir() -> Path:
    """pac_interfaces' .msg files (the installed share directory of the package)."""
    from ament_index_python.packages import get_package_share_directory

    return Path(get_package_share_directory("pac_interfaces")) / "msg"


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
