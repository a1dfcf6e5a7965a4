"""The names of a registry of variants, read from it when first asked for.

A parameter's choices are the keys of the registry of its variants (``law``: pac_controller.laws.LAWS),
but the registry imports the parameters' module to build its entries, so the parameters cannot import
the registry when they are defined. :class:`RegistryNames` is the sequence of the names, read from the
registry on first use (membership, iteration, the help text), by which time both modules are loaded.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Sequence
from typing import Any, overload


class RegistryNames(Sequence[str]):
    """The keys of the dict ``registry`` of ``module`` whose entries ``keep`` accepts, in the
    registry's order, read on first use. Compared by identity (``tuple(names)`` for its values)."""

    def __init__(self, module: str, registry: str, keep: Callable[[Any], bool] = lambda entry: True) -> None:
        self._where, self._keep = (module, registry), keep
        self._names: tuple[str, ...] | None = None

    def _read(self) -> tuple[str, ...]:
        if self._names is None:
            registry = getattr(importlib.import_module(self._where[0]), self._where[1])
            self._names = tuple(name for name, entry in registry.items() if self._keep(entry))
        return self._names

    @overload
    def __getitem__(self, index: int) -> str: ...
    @overload
    def __getitem__(self, index: slice) -> tuple[str, ...]: ...
    def __getitem__(self, index: int | slice) -> str | tuple[str, ...]:
        return self._read()[index]

    def __len__(self) -> int:
        return len(self._read())

    def __repr__(self) -> str:
        return repr(self._read())
