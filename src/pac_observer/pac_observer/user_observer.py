"""A user's own observer, from a Python file: ``-p observer:=path/to/my_observer.py`` (docs/laws.md,
"Your own observer").

The file is a module with these names (``examples/my_observer.py`` is a worked one):

- ``GIVES``: what the observer gives a law besides z_hat, any of ``"theta_hat"``,
  ``"contact_force_hat"`` (F_hat). The composition rules read it as they read a registry line's
  (``observers.ObserverEntry.gives``): a law that needs what it does not give is refused before
  the run, in one line (``pac_rig.composition``).
- ``READS`` (optional; default none): the sensor channels it reads besides the frame positions,
  of :data:`OPTIONAL_READINGS` (a run on sensors without one is refused, as for a registry line).
- ``Observer``: a class built as ``Observer(pantograph, track, params, sample_period)`` (the
  nominal pantograph, the track, the observer's parameters ``ObserverParameters``, the sample
  period [s]) with

  - ``update(tick, y, actuator_force, head_acceleration) -> pac_observer.observer.Estimate``:
    the sample of ``tick`` (y = (z1, z2) as the sensors give them, the actuator's force, the head
    accelerometer's reading, NaN where there is none); ticks come in order, with gaps where
    samples were lost;
  - ``reset()``: forget everything (the node's restart);
  - ``tick``: the last tick it took, -1 before the first;
  - ``warm_up()`` (optional): load what its first sample would otherwise load.

  An estimate with a non-finite value never reaches the actuator: the controller's safety chain
  answers it with the fallback, as it does for pac's observers.

It runs at Python speed, in ``observer_node``, ``simulate`` and campaigns: the offline loop steps
the cores tick by tick (``closed_loop.run_cores``), as for any core without a compiled form; the
compiled loop and the batch run pac's registered observers only.
"""

from __future__ import annotations

import functools
import inspect
from dataclasses import dataclass
from types import ModuleType
from typing import Any

from pac_common import user_file
from pac_common.parameters import ParameterError

from .observers import ObserverEntry

#: What an observer file's GIVES may name (a law's NEEDS besides z_hat).
ESTIMATE_PARTS = ("theta_hat", "contact_force_hat")
#: What an observer file's READS may name: the readings ``update`` is given besides y and the
#: actuator's force, each with what it is (the sensor channel's name in pac_plant.hardware.sensors).
OPTIONAL_READINGS = {"head_acceleration": "a head accelerometer"}
#: What the class must have.
METHODS = ("update", "reset")
#: The section of docs/laws.md that describes the protocol (named in every refusal).
PROTOCOL = "docs/laws.md, 'Your own observer'"


@dataclass(frozen=True)
class ObserverFile:
    """An observer file, loaded and checked against the protocol (the module docstring)."""

    path: str  # as the user named it
    digest: str  # SHA-256 of its text (a campaign point's key holds it)
    entry: ObserverEntry  # as a registry line would give it (no compiled update)
    cls: type


def refuse(path: str, why: str) -> ParameterError:
    """The one-line refusal of observer file ``path``."""
    return ParameterError("observer", path, f"an observer file ({PROTOCOL}): {why}")


#: Loaded files by absolute path: a file is imported once per process.
_LOADED: dict[str, ObserverFile] = {}


def load_observer_file(path: str) -> ObserverFile:
    """The observer of file ``path``, imported from the file and checked; ParameterError, one line,
    for a missing file, one that fails to import, one off the protocol, and one whose text changed
    since this process imported it (an observer is fixed for a run)."""
    return user_file.load_once(path, _LOADED, "pac_user_observer", _check, functools.partial(refuse, path))


def _names(
    path: str, module: object, name: str, allowed: tuple[str, ...], default: object
) -> tuple[str, ...]:
    """The collection of names ``name`` of ``module``, each of ``allowed``."""
    value: Any = getattr(module, name, default)
    if value is None:
        raise refuse(path, f"it does not define {name}")
    if isinstance(value, str) or not all(isinstance(n, str) for n in value):
        raise refuse(path, f"{name} = {value!r} is not a collection of names")
    unknown = sorted(set(value) - set(allowed))
    if unknown:
        raise refuse(path, f"{name} names {', '.join(unknown)}; it may name {', '.join(allowed)}")
    return tuple(value)


def _check(path: str, digest: str, module: ModuleType) -> ObserverFile:
    """The protocol's names of ``module``, checked."""
    gives = _names(path, module, "GIVES", ESTIMATE_PARTS, None)
    reads = _names(path, module, "READS", tuple(OPTIONAL_READINGS), ())
    cls = getattr(module, "Observer", None)
    if cls is None:
        raise refuse(path, "it does not define Observer")
    if not inspect.isclass(cls):
        raise refuse(path, "Observer is not a class")
    for method in METHODS:
        if not callable(getattr(cls, method, None)):
            raise refuse(path, f"Observer has no method {method}")
    entry = ObserverEntry(
        frozenset(gives),
        f"{path}:Observer",
        f"the observer of the file {path}",
        reads=tuple((channel, OPTIONAL_READINGS[channel]) for channel in reads),
    )
    return ObserverFile(path, digest, entry, cls)


class _Built:
    """Builds a file's Observer, a failure of its constructor being a refusal of the file."""

    def __init__(self, loaded: ObserverFile) -> None:
        self.loaded = loaded

    def __call__(self, *args: object) -> object:
        try:
            return self.loaded.cls(*args)
        except ParameterError:
            raise
        except Exception as exc:  # noqa: BLE001 - the user's constructor failing is a refusal of the file
            path = self.loaded.path
            raise refuse(path, f"building Observer raised {user_file.where(exc, path)}") from None


def builder(path: str) -> _Built:
    """What builds the observer of file ``path`` (as a registered core class is called)."""
    return _Built(load_observer_file(path))


__all__ = ["ESTIMATE_PARTS", "OPTIONAL_READINGS", "ObserverFile", "builder", "load_observer_file", "refuse"]
