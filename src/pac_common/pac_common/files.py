"""Reading the suite's input files and writing its output files, one discipline for all.

Reading (:func:`read_bytes`, :func:`read_text`, :func:`read_yaml`): a regular file only
(a FIFO, a device or a directory is refused before it is opened, so nothing blocks or
streams without end), at most a stated number of bytes for its kind (:data:`MAX_BYTES`),
UTF-8 text, and YAML through :func:`load_yaml`: the safe loader, with no aliases, no key
given twice, only scalar keys, at most :data:`MAX_DEPTH` levels of nesting and integers of
at most :data:`MAX_INTEGER_DIGITS` digits. Every refusal is a :class:`FileInputError` whose
message is one line and quotes at most a short prefix of a value (:func:`excerpt`).

Writing (:func:`write_atomic`): the content goes to a temporary name beside the target and
is renamed over it when complete, so a full disk or a killed process never leaves a
half-written file under the target's name.
"""

from __future__ import annotations

import contextlib
import os
import re
import stat
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

import yaml

#: Size caps by kind of file, in bytes: far above any file the suite ships or writes.
MAX_BYTES = {
    "params": 256 << 10,  # --params-file of the nodes and the offline tools
    "catenary": 256 << 10,
    "pantograph": 256 << 10,
    "scenario": 64 << 10,
    "spec": 256 << 10,  # a campaign SPEC
    "metadata": 4 << 20,  # a bag's metadata.yaml
    "runs": 256 << 20,  # a campaign's runs.jsonl
}
#: Nesting levels of a YAML document (mappings and lists): the suite's files use four.
MAX_DEPTH = 32
#: Digits of an integer in YAML (Python itself refuses more than 4300 with a bare ValueError).
MAX_INTEGER_DIGITS = 100
#: Characters of a value quoted in an error message.
EXCERPT_CHARS = 240


class FileInputError(ValueError):
    """An input that cannot be used; the message is one line. ``mark``: (line, column), 1-based,
    where a YAML problem was found, else None; ``problem``: the message without the file."""

    def __init__(
        self, source: str, problem: str, mark: tuple[int, int] | None = None, duplicate: Any = None
    ) -> None:
        self.source, self.problem, self.mark = source, problem, mark
        self.duplicate = duplicate  # the key given twice, when that is the problem
        where = f", line {mark[0]}, column {mark[1]}" if mark else ""
        super().__init__(f"{source}{where}: {problem}")


def excerpt(value: Any, limit: int = EXCERPT_CHARS) -> str:
    """``repr(value)`` cut to ``limit`` characters (a value may be a whole file)."""
    if isinstance(value, str | bytes) and len(value) > limit:
        value = value[: limit + 1]  # repr of the prefix only: never of a huge string
    text = repr(value) if not isinstance(value, list | dict | tuple) else _container_repr(value, limit)
    return text if len(text) <= limit else text[:limit] + "..."


def _container_repr(value: Any, limit: int) -> str:
    """repr of a container without building it whole (a list of a million values)."""
    if isinstance(value, dict):
        parts = (f"{excerpt(k, limit)}: {excerpt(v, limit)}" for k, v in value.items())
        left, right = "{", "}"
    else:
        parts = (excerpt(v, limit) for v in value)
        left, right = ("[", "]") if isinstance(value, list) else ("(", ")")
    out = left
    for i, part in enumerate(parts):
        out += (", " if i else "") + part
        if len(out) > limit:
            return out
    return out + ("," if isinstance(value, tuple) and len(value) == 1 else "") + right


# -- reading --------------------------------------------------------------------------------------
def _kind_of(mode: int) -> str:
    if stat.S_ISDIR(mode):
        return "a directory"
    if stat.S_ISFIFO(mode):
        return "a FIFO"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "not a regular file"


def read_bytes(path: str | os.PathLike[str], kind: str) -> bytes:
    """The bytes of the regular file ``path``, at most ``MAX_BYTES[kind]``; else FileInputError."""
    limit = MAX_BYTES[kind]
    source = f"{kind} file {excerpt(str(path))}"
    try:
        mode = os.stat(path).st_mode
    except (OSError, ValueError) as exc:  # ValueError: a NUL in the path
        raise FileInputError(source, f"cannot be read ({_reason(exc)})") from None
    if not stat.S_ISREG(mode):
        raise FileInputError(source, f"is {_kind_of(mode)}: allowed a regular file")
    try:
        # O_NONBLOCK: a file swapped for a FIFO after the check still cannot block the open.
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
    except OSError as exc:
        raise FileInputError(source, f"cannot be read ({_reason(exc)})") from None
    try:
        mode = os.fstat(fd).st_mode
        if not stat.S_ISREG(mode):
            raise FileInputError(source, f"is {_kind_of(mode)}: allowed a regular file")
        with os.fdopen(fd, "rb", closefd=False) as handle:
            data = handle.read(limit + 1)
    except OSError as exc:
        raise FileInputError(source, f"cannot be read ({_reason(exc)})") from None
    finally:
        os.close(fd)
    if len(data) > limit:
        raise FileInputError(source, f"is larger than {limit} bytes, the most a {kind} file may be")
    return data


def decode(data: bytes, source: str) -> str:
    """UTF-8 text; FileInputError naming the first bad byte's offset."""
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise FileInputError(
            source, f"is not UTF-8 text (byte 0x{data[exc.start]:02x} at offset {exc.start})"
        ) from None


def read_text(path: str | os.PathLike[str], kind: str) -> str:
    """The UTF-8 text of the regular file ``path`` (see :func:`read_bytes`)."""
    return decode(read_bytes(path, kind), f"{kind} file {excerpt(str(path))}")


def read_yaml(path: str | os.PathLike[str], kind: str) -> Any:
    """The YAML document in the regular file ``path``, read by :func:`load_yaml`."""
    return load_yaml(read_text(path, kind), f"{kind} file {excerpt(str(path))}")


def _reason(exc: Exception) -> str:
    if isinstance(exc, OSError):
        return exc.strerror or type(exc).__name__
    return str(exc).splitlines()[0][:EXCERPT_CHARS] if str(exc) else type(exc).__name__


# -- YAML -----------------------------------------------------------------------------------------
class Map(dict):
    """A mapping that knows where each of its values starts in the file (1-based line, column)."""

    marks: dict[Any, tuple[int, int]]
    start: tuple[int, int]


class Seq(list):
    """A list that knows where each of its items starts in the file."""

    marks: list[tuple[int, int]]
    start: tuple[int, int]


def _mark(node: yaml.Node | yaml.Event) -> tuple[int, int]:
    return node.start_mark.line + 1, node.start_mark.column + 1


class _Refused(Exception):
    def __init__(self, problem: str, mark: tuple[int, int], duplicate: Any = None) -> None:
        self.problem, self.mark, self.duplicate = problem, mark, duplicate


class _Loader(yaml.SafeLoader):
    """The safe loader without aliases, duplicate keys, unhashable keys, deep nesting or
    overlong integers; mappings and lists keep their positions (:class:`Map`, :class:`Seq`)."""

    depth = 0

    def compose_node(self, parent: Any, index: Any) -> Any:
        if self.check_event(yaml.AliasEvent):
            raise _Refused("an alias (*name): not allowed, write the value out", _mark(self.peek_event()))
        self.depth += 1
        if self.depth > MAX_DEPTH:
            raise _Refused(f"nested deeper than {MAX_DEPTH} levels", _mark(self.peek_event()))
        try:
            return super().compose_node(parent, index)
        finally:
            self.depth -= 1


def _construct_map(loader: _Loader, node: yaml.MappingNode) -> Map:
    loader.flatten_mapping(node)
    out = Map()
    out.marks, out.start = {}, _mark(node)
    for key_node, value_node in node.value:
        if not isinstance(key_node, yaml.ScalarNode):
            raise _Refused("a key that is a list or a mapping: allowed a plain key", _mark(key_node))
        key = loader.construct_object(key_node, deep=True)
        if key in out:
            raise _Refused(f"key {excerpt(key)} given twice: allowed each key once", _mark(key_node), key)
        out[key] = loader.construct_object(value_node, deep=True)
        out.marks[key] = _mark(value_node)
    return out


def _construct_seq(loader: _Loader, node: yaml.SequenceNode) -> Seq:
    out = Seq(loader.construct_object(child, deep=True) for child in node.value)
    out.marks, out.start = [_mark(child) for child in node.value], _mark(node)
    return out


def _construct_int(loader: _Loader, node: yaml.ScalarNode) -> int:
    digits = sum(c.isalnum() for c in str(node.value))
    if digits > MAX_INTEGER_DIGITS:
        raise _Refused(f"an integer of {digits} digits: allowed at most {MAX_INTEGER_DIGITS}", _mark(node))
    return int(loader.construct_yaml_int(node))


_Loader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _construct_map)
_Loader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_SEQUENCE_TAG, _construct_seq)
_Loader.add_constructor("tag:yaml.org,2002:int", _construct_int)
# ``1e4`` is a number to rcl (and YAML 1.2); PyYAML's YAML 1.1 reads it as a string without a dot.
_Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?[0-9][0-9_]*(?:\.[0-9_]*)?[eE][-+]?[0-9]+$"),
    list("-+0123456789"),
)


def load_yaml(text: str, source: str) -> Any:
    """The YAML document ``text`` (``source`` names it in errors) by the safe loader with the
    limits above; None for an empty document. Mappings are :class:`Map`, lists :class:`Seq`."""
    loader = None
    try:
        loader = _Loader(text)  # refuses control characters here
        return loader.get_single_data()
    except _Refused as exc:
        raise FileInputError(source, exc.problem, exc.mark, exc.duplicate) from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        problem = getattr(exc, "problem", None) or _reason(exc)
        raise FileInputError(
            source, f"is not valid YAML ({problem})", (mark.line + 1, mark.column + 1) if mark else None
        ) from None
    except (RecursionError, ValueError, TypeError) as exc:  # a constructor's own refusal
        raise FileInputError(source, f"is not valid YAML ({_reason(exc)})") from None
    finally:
        if loader is not None:
            loader.dispose()


# -- writing --------------------------------------------------------------------------------------
@contextlib.contextmanager
def write_atomic(path: str | os.PathLike[str], mode: str = "w", **open_args: Any) -> Iterator[IO[Any]]:
    """A file to write ``path``'s new content in: a temporary file beside it, renamed over
    ``path`` when the block ends without error, removed when it raises (the error propagates:
    ``path`` is then as it was)."""
    target = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".partial", dir=target.parent)
    try:
        with os.fdopen(fd, mode, **open_args) as handle:
            yield handle
            handle.flush()
            os.fsync(handle.fileno())
        os.chmod(tmp, 0o644)
        os.replace(tmp, target)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def write_text_atomic(path: str | os.PathLike[str], text: str) -> None:
    """``path`` holds ``text`` (UTF-8), or, on an error, what it held before."""
    with write_atomic(path, "w", encoding="utf-8", newline="") as handle:
        handle.write(text)
