"""A user's Python file as a module: a law of one's own (``law:=my_law.py``) or an observer
(``observer:=my_observer.py``). Imported from its path (not from ``sys.path``) under a name of its
own, its text's digest kept (a campaign point's key holds it; an edit after the import is
refused), and every failure one line, through the caller's refusal.

``refuse(why)`` makes the caller's one-line :class:`~pac_common.parameters.ParameterError` (which
parameter, which file, which protocol); this module only says why.
"""

from __future__ import annotations

import hashlib
import importlib.util
import sys
import traceback
from collections.abc import Callable, MutableMapping
from pathlib import Path
from types import ModuleType
from typing import Protocol, TypeVar

from .parameters import ParameterError

Refusal = Callable[[str], ParameterError]


class Loaded(Protocol):
    """A file as its protocol's checker returns it: it keeps the digest of the text it came from."""

    @property
    def digest(self) -> str: ...


LoadedT = TypeVar("LoadedT", bound=Loaded)


def load_once(
    path: str,
    loaded: MutableMapping[str, LoadedT],
    prefix: str,
    check: Callable[[str, str, ModuleType], LoadedT],
    refuse: Refusal,
) -> LoadedT:
    """The file ``path`` imported (:func:`import_file`) and checked (``check(path, digest, module)``)
    once per process, kept in ``loaded`` by absolute path; the refusal when its text changed since
    this process imported it: what it defines is fixed for a run, so an edit is not taken up
    silently (by a node's retune, or a campaign worker's next point)."""
    digest = file_digest(path, refuse)
    key = str(Path(path).resolve())
    known = loaded.get(key)
    if known is None:
        known = loaded[key] = check(path, digest, import_file(path, digest, prefix, refuse))
    elif known.digest != digest:
        raise refuse("its text changed since this process imported it (start again to run the new text)")
    return known


def file_digest(path: str, refuse: Refusal) -> str:
    """SHA-256 of the text of ``path``; the refusal when it cannot be read."""
    try:
        return hashlib.sha256(Path(path).read_bytes()).hexdigest()
    except FileNotFoundError:
        raise refuse("no such file") from None
    except OSError as exc:
        raise refuse(f"cannot read it ({exc.strerror or exc})") from None


def import_file(path: str, digest: str, prefix: str, refuse: Refusal) -> ModuleType:
    """The module of ``path`` under a name of its own, ``prefix`` + its stem + its digest's head
    (two files both called my_law.py do not meet); the refusal when it does not import."""
    name = f"{prefix}_{Path(path).stem}_{digest[:12]}"
    spec = importlib.util.spec_from_file_location(name, path)
    if spec is None or spec.loader is None:
        raise refuse("not a Python module")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # numba and dataclasses look the module up by name
    try:
        spec.loader.exec_module(module)
    except Exception as exc:  # noqa: BLE001 - whatever the user's file raises is its refusal, in one line
        del sys.modules[name]
        raise refuse(f"importing it raised {where(exc, path)}") from None
    return module


def where(exc: BaseException, path: str) -> str:
    """``exc`` in one line, with the line of ``path`` it came from where there is one."""
    text = f"{type(exc).__name__}: {exc}".splitlines()[0]
    if isinstance(exc, SyntaxError) and exc.lineno is not None:
        return f"{text} (line {exc.lineno})"
    lines = [f.lineno for f in traceback.extract_tb(exc.__traceback__) if Path(f.filename) == Path(path)]
    return f"{text} (line {lines[-1]})" if lines else text


__all__ = ["Loaded", "Refusal", "file_digest", "import_file", "load_once", "where"]
