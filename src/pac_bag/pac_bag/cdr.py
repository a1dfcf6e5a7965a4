"""Whole runs of ROS 2 messages as CDR at once: numpy structured arrays laid out per the CDR rules.

A message type without sequences has a fixed CDR layout once the length of each of its
strings is fixed (pac messages: ``header.frame_id`` is the only string).  The layout is
derived from the type's field definitions (a rosbags typestore parsed from the .msg files),
so a field added to a .msg file needs no code here.  CDR rules (XCDR1, as rmw_fastrtps and
rosbags write it): a 4-byte encapsulation header (``00 01 00 00``: CDR little endian), then
every primitive aligned to its size (at most 8) counted from the end of that header; a
string is a 4-aligned uint32 length (bytes + NUL) followed by the bytes and the NUL; fixed
arrays are their elements back to back; nested messages add no alignment of their own; no
padding after the last field.  Pure numpy, no ROS.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from rosbags.interfaces import Nodetype

ENCAPSULATION_LE = b"\x00\x01\x00\x00"

_PRIMITIVES: dict[str, str] = {
    "bool": "?",
    "byte": "u1",
    "char": "u1",
    "int8": "i1",
    "uint8": "u1",
    "int16": "<i2",
    "uint16": "<u2",
    "int32": "<i4",
    "uint32": "<u4",
    "int64": "<i8",
    "uint64": "<u8",
    "float32": "<f4",
    "float64": "<f8",
}


class LayoutError(ValueError):
    """The type has no fixed CDR layout (a sequence, or strings of varying length in one batch)."""


@dataclass(frozen=True)
class CdrLayout:
    """The fixed CDR layout of one message type (with fixed string lengths).

    ``dtype`` is a little-endian structured dtype whose ``itemsize`` is the serialised size,
    encapsulation header included; its gaps are the CDR padding (zero).  Field names are the
    flattened field paths (``header.stamp.sec``, ``z``); each string has its length word as
    ``<path>#len`` and its bytes as ``<path>``; ``#encapsulation`` is the header.
    """

    typename: str
    dtype: np.dtype
    fields: tuple[str, ...]  # value fields (flattened paths), in message order
    strings: tuple[tuple[str, int], ...]  # (path, byte length without the NUL)

    @property
    def size(self) -> int:
        return self.dtype.itemsize

    def pack(self, columns: Mapping[str, Any], count: int) -> np.ndarray:
        """``count`` messages from flat columns (path -> array of length ``count`` or a scalar)."""
        out = np.zeros(count, dtype=self.dtype)
        out["#encapsulation"] = np.frombuffer(ENCAPSULATION_LE, dtype=np.uint8)
        for path, length in self.strings:
            out[f"{path}#len"] = length + 1
        for path in self.fields:
            out[path] = columns[path]
        return out


def layout(typestore: Any, typename: str, strings: Mapping[str, int] | None = None) -> CdrLayout:
    """The CDR layout of ``typename``; ``strings`` gives each string field's byte length (default 0).

    Raises :class:`LayoutError` for a type with sequences (no fixed layout)."""
    strings = dict(strings or {})
    names: list[str] = ["#encapsulation"]
    formats: list[Any] = [("u1", (4,))]
    offsets: list[int] = [0]
    fields: list[str] = []
    string_list: list[tuple[str, int]] = []
    offset = 0  # from the end of the encapsulation header (CDR alignment origin)

    def add(name: str, fmt: Any, align: int, size: int) -> None:
        nonlocal offset
        offset = (offset + align - 1) // align * align
        names.append(name)
        formats.append(fmt)
        offsets.append(4 + offset)
        offset += size

    def walk(tname: str, prefix: str) -> None:
        for name, (node, spec) in typestore.fielddefs[tname][1]:
            path = f"{prefix}{name}"
            if node == Nodetype.NAME:
                walk(spec, f"{path}.")
            elif node == Nodetype.BASE:
                base, bound = spec
                if base == "string":
                    if bound:
                        raise LayoutError(f"{tname}.{name}: bounded strings are not supported")
                    length = strings.pop(path, 0)
                    add(f"{path}#len", "<u4", 4, 4)
                    add(path, f"S{length}" if length else "V0", 1, length + 1)
                    if length:
                        fields.append(path)
                    string_list.append((path, length))
                else:
                    fmt = _primitive(tname, name, base)
                    size = np.dtype(fmt).itemsize
                    add(path, fmt, size, size)
                    fields.append(path)
            elif node == Nodetype.ARRAY:
                (elem_node, elem_spec), count = spec
                if elem_node != Nodetype.BASE or elem_spec[0] == "string":
                    raise LayoutError(f"{tname}.{name}: arrays of {elem_spec} are not supported")
                fmt = _primitive(tname, name, elem_spec[0])
                size = np.dtype(fmt).itemsize
                add(path, (fmt, (count,)), size, size * count)
                fields.append(path)
            else:
                raise LayoutError(f"{tname}.{name}: a sequence has no fixed CDR layout")

    walk(typename, "")
    if strings:
        raise LayoutError(f"{typename}: no string field {sorted(strings)[0]!r}")
    # "V0" (an empty string's zero-size placeholder) is dropped: its NUL is padding (zero).
    keep = [i for i, f in enumerate(formats) if f != "V0"]
    dtype = np.dtype(
        {
            "names": [names[i] for i in keep],
            "formats": [formats[i] for i in keep],
            "offsets": [offsets[i] for i in keep],
            "itemsize": 4 + offset,
        }
    )
    return CdrLayout(typename, dtype, tuple(fields), tuple(string_list))


def _primitive(tname: str, name: str, base: str) -> str:
    try:
        return _PRIMITIVES[base]
    except KeyError:
        raise LayoutError(f"{tname}.{name}: type {base} is not supported") from None


def string_fields(typestore: Any, typename: str, prefix: str = "") -> list[str]:
    """Flattened paths of the (unbounded) string fields of ``typename``."""
    out: list[str] = []
    for name, (node, spec) in typestore.fielddefs[typename][1]:
        if node == Nodetype.NAME:
            out += string_fields(typestore, spec, f"{prefix}{name}.")
        elif node == Nodetype.BASE and spec[0] == "string":
            out.append(f"{prefix}{name}")
    return out


def serialize_many(typestore: Any, typename: str, columns: Mapping[str, Any], count: int) -> np.ndarray:
    """``count`` messages of ``typename`` as CDR: an array of shape (count, size) of uint8.

    ``columns`` maps every flattened field path to an array of ``count`` values (or one value
    for all); strings as ``str``/``bytes`` values.  Raises :class:`LayoutError` when the strings
    of one field differ in length (no fixed layout: serialise such messages one by one)."""
    lengths: dict[str, int] = {}
    cols = dict(columns)
    for path in string_fields(typestore, typename):
        values = cols.get(path, "")
        distinct = {values} if isinstance(values, (str, bytes)) else set(values)
        encoded = {v: v.encode() if isinstance(v, str) else bytes(v) for v in distinct}
        sizes = {len(v) for v in encoded.values()}
        if len(sizes) != 1:
            raise LayoutError(f"{typename}.{path}: strings of different lengths in one batch")
        lengths[path] = sizes.pop()
        if lengths[path]:
            if len(encoded) == 1:
                cols[path] = next(iter(encoded.values()))  # one value for all (the usual frame_id)
            else:
                cols[path] = np.array([encoded[v] for v in values], dtype=f"S{lengths[path]}")
    lay = layout(typestore, typename, lengths)
    return lay.pack(cols, count).view(np.uint8).reshape(count, lay.size)
