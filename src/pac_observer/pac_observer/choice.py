"""The observer a run names: a line of the registry (``observers.OBSERVERS``) or a user's observer
file (``user_observer``), looked up the same way by the composition rules, the cores and the batch."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from .observers import OBSERVERS, ObserverEntry, core_class
from .user_observer import builder, load_observer_file


def observer_entry(name: str) -> ObserverEntry:
    """The entry of observer ``name``: the registry's, or that of a user's observer file (a path
    ending in .py, loaded from the file: ParameterError in one line when it cannot be)."""
    if name in OBSERVERS:
        return OBSERVERS[name]
    return load_observer_file(name).entry


def observer_builder(name: str) -> Callable[..., Any]:
    """What builds observer ``name`` from (pantograph, track, params, sample_period): its core class,
    or a user's observer file's class."""
    if name in OBSERVERS:
        return core_class(name)
    return builder(name)


__all__ = ["observer_builder", "observer_entry"]
