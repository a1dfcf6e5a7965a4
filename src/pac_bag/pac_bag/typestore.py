"""The rosbags type stores of pac bags: pac_interfaces parsed from the .msg files, with ROS 2 Jazzy's types.

:func:`typestore` holds every Jazzy type (a reader may meet any of them). A writer knows the types
it writes before it writes them, so :func:`writer_typestore` holds only those and the types they
name, read from the installed .msg files; rosbags' whole Jazzy store (185 types) costs a run's
start 0.1 s to import. Both give a type the same definition, message text and hash (tested).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from rosbags.interfaces import Nodetype
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore


def interface_dir() -> Path:
    """pac_interfaces' .msg files (the installed share directory of the package)."""
    from ament_index_python.packages import get_package_share_directory

    return Path(get_package_share_directory("pac_interfaces")) / "msg"


_PAC_TYPES: dict[str, Any] = {}
_TYPESTORE: Typestore | None = None


def pac_types() -> dict[str, Any]:
    """The field definitions of pac_interfaces' messages, parsed from their .msg files."""
    if not _PAC_TYPES:
        for msg in sorted(interface_dir().glob("*.msg")):
            _PAC_TYPES.update(get_types_from_msg(msg.read_text(), f"pac_interfaces/msg/{msg.stem}"))
    return _PAC_TYPES


def typestore() -> Typestore:
    """ROS 2 Jazzy types plus pac_interfaces, parsed from the .msg files."""
    global _TYPESTORE
    if _TYPESTORE is None:
        store = get_typestore(Stores.ROS2_JAZZY)
        store.register(pac_types())
        _TYPESTORE = store
    return _TYPESTORE


def writer_typestore() -> Typestore:
    """A store of pac_interfaces and the types they name (a new store each call: a writer adds the
    other types it writes with :func:`ensure_type`)."""
    store = get_typestore(Stores.EMPTY)
    for typename in pac_types():
        ensure_type(store, typename)
    return store


def ensure_type(store: Typestore, typename: str) -> None:
    """Register ``typename`` and every type it names in ``store``, each from its installed .msg
    file, or from rosbags' Jazzy store where none is installed. A type neither knows is left out:
    the store's own error names it when it is used."""
    wanted = [typename]
    while wanted:
        name = wanted.pop()
        if name in store.fielddefs:
            continue
        found = _definition(name)
        if found is None:
            continue
        store.register({name: found})
        wanted += _named_types(found)


def _definition(typename: str) -> Any:
    """The field definition of ``typename`` (``pkg/msg/Name``): pac's, the installed .msg file's,
    else the Jazzy store's; None when none has it."""
    if typename in pac_types():
        return pac_types()[typename]
    package, kind, name = (typename.split("/") + ["", ""])[:3]
    if kind == "msg" and name:
        try:
            from ament_index_python.packages import PackageNotFoundError, get_package_share_directory

            path = Path(get_package_share_directory(package)) / "msg" / f"{name}.msg"
        except (ImportError, PackageNotFoundError, ValueError):
            path = None
        if path is not None and path.is_file():
            return get_types_from_msg(path.read_text(), typename)[typename]
    return typestore().fielddefs.get(typename)


def _named_types(definition: Any) -> list[str]:
    """The message types a field definition's fields name (nested, or as array or sequence elements)."""
    named = []
    for _, (node, spec) in definition[1]:
        if node in (Nodetype.ARRAY, Nodetype.SEQUENCE):
            node, spec = spec[0]
        if node == Nodetype.NAME:
            named.append(spec)
    return named
