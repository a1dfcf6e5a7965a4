"""Data files (YAML) read with positions and checked value by value: one line per refusal.

The catenary file (``pac_plant.catenary.catenary_file``) and the pantograph file
(``pac_model.pantograph_file``) are both read by these helpers, so that every data file of
the suite refuses a bad value the same way: one line naming the file, the line and column,
the key, the value and what is allowed (a ``ParameterError``: the nodes and tools print it and
exit 2).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from .files import FileInputError, Map, Seq, excerpt, load_yaml, read_text
from .parameters import ParameterError

__all__ = ["DataFileError", "Map", "Presets", "Reader", "Seq", "interval"]


class DataFileError(ParameterError):
    """A data file that cannot be used; the message is one line. ``KIND`` names the file's kind."""

    KIND = "data"

    def __init__(self, source: str, key: str, value: Any, allowed: str, where: str = "") -> None:
        self.name = key
        self.value = value
        self.allowed = allowed
        ValueError.__init__(
            self, f"invalid {self.KIND} file '{source}'{where}: '{key}' = {excerpt(value)}: allowed {allowed}"
        )


# -- checking ---------------------------------------------------------------------------------------
class Reader:
    """Reads values out of the parsed file, each check naming its key path and position; a
    refusal is ``error`` (a :class:`DataFileError` subclass naming the file's kind)."""

    def __init__(self, source: str, error: type[DataFileError] = DataFileError) -> None:
        self.source = source
        self.error = error

    def fail(self, key: str, value: Any, allowed: str, mark: tuple[int, int] | None) -> DataFileError:
        where = f", line {mark[0]}, column {mark[1]}" if mark else ""
        return self.error(self.source, key, value, allowed, where)

    def parse(self, text: str, top_keys: tuple[str, ...]) -> Map:
        """The file's top-level mapping (positions kept); invalid YAML, a key given twice, a file
        that is not a mapping or an unknown top-level key: refused."""
        try:
            raw = load_yaml(text, self.source)
        except FileInputError as exc:
            if exc.duplicate is not None:
                raise self.fail(str(exc.duplicate), "given twice", "each key once", exc.mark) from None
            raise self.fail("(YAML)", exc.problem, "valid YAML", exc.mark) from None
        if not isinstance(raw, Map):
            raise self.fail("(file)", raw, f"a mapping with the keys {', '.join(top_keys)}", None)
        self.known(raw, "", top_keys)
        return raw

    def text(self, parent: Map, name: str) -> str:
        """A required non-empty string, whitespace runs folded to one space."""
        value = parent.get(name)
        if not isinstance(value, str) or not value.strip():
            raise self.fail(name, value, "a non-empty string", parent.marks.get(name, parent.start))
        return " ".join(value.split())

    def mapping(
        self, parent: Map, name: str, path: str, keys: tuple[str, ...], optional: bool = False
    ) -> Map:
        key = f"{path}{name}"
        if name not in parent:
            if optional:
                empty = Map()
                empty.marks, empty.start = {}, getattr(parent, "start", (0, 0))
                return empty
            raise self.fail(key, None, f"a mapping with {', '.join(keys)} (it is missing)", parent.start)
        value = parent[name]
        if not isinstance(value, Map):
            raise self.fail(key, value, f"a mapping with {', '.join(keys)}", parent.marks[name])
        self.known(value, key + ".", keys)
        return value

    def known(self, mapping: Map, path: str, keys: tuple[str, ...]) -> None:
        for k in mapping:
            if k not in keys:
                raise self.fail(
                    f"{path}{k}", mapping[k], f"one of the keys {', '.join(keys)}", mapping.marks[k]
                )

    def number(
        self,
        parent: Map,
        name: str,
        path: str,
        unit: str,
        low: float = 0.0,
        high: float = math.inf,
        *,
        low_open: bool = True,
        default: float | None = None,
    ) -> float:
        key = f"{path}{name}"
        if name not in parent:
            if default is not None:
                return default
            raise self.fail(
                key, None, f"{interval(low, high, low_open)} {unit} (it is missing)".strip(), parent.start
            )
        return self.check_number(parent[name], key, unit, low, high, low_open, parent.marks[name])

    def check_number(
        self, value: Any, key: str, unit: str, low: float, high: float, low_open: bool, mark: tuple[int, int]
    ) -> float:
        ok = isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
        if ok:
            ok = (value > low if low_open else value >= low) and value <= high
        if not ok:
            raise self.fail(
                key, value, f"a finite number in {interval(low, high, low_open)} {unit}".strip(), mark
            )
        return float(value)

    def numbers(
        self,
        parent: Map,
        name: str,
        path: str,
        unit: str,
        low: float,
        high: float,
        *,
        low_open: bool,
        count: int | None,
    ) -> tuple[float, ...]:
        key = f"{path}{name}"
        size = "a non-empty list" if count is None else f"a list of {count}"
        what = f"{size} of finite numbers in {interval(low, high, low_open)} {unit}".strip()
        value = parent.get(name)
        if not isinstance(value, Seq) or not value or (count is not None and len(value) != count):
            raise self.fail(key, value, what, parent.marks.get(name, parent.start))
        return tuple(
            self.check_number(v, f"{key}[{i}]", unit, low, high, low_open, m)
            for i, (v, m) in enumerate(zip(value, value.marks, strict=True))
        )


def interval(low: float, high: float, low_open: bool) -> str:
    left = "(" if low_open or low == -math.inf else "["
    right = ")" if high == math.inf else "]"
    return f"{left}{low:g}, {high:g}{right}"


# -- presets and paths --------------------------------------------------------------------------
class Presets:
    """The shipped data files of one kind, ``<repository>/<folder>/<name>.yaml``, found from the
    location of the module ``anchor`` (its source tree or its install tree), and how a
    parameter's value names a file: a path (with ``/`` or a .yaml/.yml ending) or a preset."""

    def __init__(self, folder: Path, default: str, parameter: str, anchor: str, doc: str) -> None:
        self.folder, self.default, self.parameter, self.anchor, self.doc = (
            folder,
            default,
            parameter,
            anchor,
            doc,
        )

    def path(self, name: str) -> Path | None:
        """The shipped preset ``name``, or None."""
        for folder in Path(self.anchor).resolve().parents:
            candidate = folder / self.folder / f"{name}.yaml"
            if candidate.is_file():
                return candidate
        return None

    def names(self) -> list[str]:
        path = self.path(self.default)
        return sorted(p.stem for p in path.parent.glob("*.yaml")) if path else []

    def resolve(self, value: str, parameter: str = "") -> Path:
        """The file ``value`` names; a name that is no preset: ParameterError (one line) naming
        ``parameter`` (default: the kind's own parameter)."""
        if "/" in value or value.endswith((".yaml", ".yml")):
            return Path(value)
        path = self.path(value)
        if path is None:
            raise ParameterError(
                parameter or self.parameter,
                value,
                f"a {self.parameter} file or a preset: one of {', '.join(self.names())} ({self.doc})",
            )
        return path

    def read(self, value: str, parameter: str = "") -> tuple[str, int, int]:
        """(path, mtime in ns, size) of the file ``value`` names: the key of a per-file cache that
        sees an edited file; unreadable: ParameterError."""
        path = self.resolve(value, parameter)
        try:
            stat = path.stat()
        except OSError as exc:
            raise ParameterError(
                parameter or self.parameter,
                value,
                f"a readable {self.parameter} file ({exc.strerror or exc})",
            ) from None
        return str(path), stat.st_mtime_ns, stat.st_size

    def text(self, path: str) -> str:
        """The file's text by the suite's reading discipline (``pac_common.files``)."""
        try:
            return read_text(path, self.parameter)
        except FileInputError as exc:
            raise ParameterError(
                self.parameter, path, f"a readable {self.parameter} file ({exc.problem})"
            ) from None
