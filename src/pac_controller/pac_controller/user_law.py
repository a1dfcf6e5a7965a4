"""A user's own control law, from a Python file: ``-p law:=path/to/my_law.py`` (docs/laws.md, "Your own law").

The file is a module with four names (``examples/my_law.py`` is a worked one):

- ``NEEDS``: what the law reads of the estimate, any of ``"z_hat"``, ``"theta_hat"``,
  ``"contact_force_hat"`` (F_hat). An estimate with a non-finite value of what it reads never
  reaches the law (the fallback answers it), and a run refuses an observer that does not give it
  (``pac_rig.composition``); values it does not declare are passed but not checked.
- ``design(setup) -> 1-D float array`` (optional; default: no constants): the law's constants,
  computed once from :class:`LawSetup` (sample period, the nominal pantograph, the track, ...).
- ``STATE_SIZE`` (optional; default 0): the length of the law's memory, a float array the
  functions below change in place.
- ``output(consts, state, t, f_r, z_hat, theta_hat, f_hat) -> u``: the unlimited force demand at
  time t [s] (f_r: F_r and its first three derivatives); it may note what ``commit`` needs in
  ``state``.
- ``restart(consts, state, has_u, u_applied)`` (optional): forget the law's memory; the next
  output should continue from the actuator's force ``u_applied`` (``has_u`` False: at rest).
  Called before the law's first command and after every command that was not its own
  (fallback, a new run, a retune).
- ``commit(consts, state, u_applied)`` (optional): the force actually commanded after the safety
  chain's limits (for anti-windup).

The law only proposes a force: the controller's one safety chain (``kernels.safety_chain``:
estimate check, fallback, slew limit, saturation; the node's watchdog) limits it, and a non-finite
demand is answered by the fallback, never sent to the actuator.

Two speeds. Plain Python functions run at Python speed: the offline loop steps the cores tick by
tick (``closed_loop.run_cores``) and the controller calls the law between the compiled parts of
the chain. When ``output``, ``restart`` and ``commit`` are all numba-compiled (``@njit``; the
defaults of the optional two are), the law is compiled into the chain (:func:`compiled_chain`):
the node's controller calls it as one compiled step and the offline loop runs it in its compiled
tick (``pac_rig.loop.block_for``), compiled once per file and process (closures of the user's
functions: numba does not cache them on disk). ``f_r`` is then a tuple of four, not an array.
"""

from __future__ import annotations

import copy
import functools
import hashlib
import importlib
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
from numba import njit
from numba.core.errors import NumbaError
from numba.extending import is_jitted

from pac_common import user_file
from pac_common.parameters import ParameterError
from pac_model.parameters import PantographParameters, TrackParameters

from .kernel_common import ACTIVE
from .kernels import CONTROLLER_PARAMS, CONTROLLER_STATE, new_state, safety_chain
from .parameters import ControllerParameters, LawParameters, ReferenceParameters

#: What a law file's NEEDS may name: the estimate's parts (ObserverEstimate's fields).
ESTIMATE_PARTS = ("z_hat", "theta_hat", "contact_force_hat")
#: The section of docs/laws.md that describes the protocol (named in every refusal).
PROTOCOL = "docs/laws.md, 'Your own law'"


@dataclass(frozen=True)
class LawSetup:
    """What a law file's ``design`` is given: the controller's parameters of the run."""

    sample_period: float  # [s]
    pantograph: PantographParameters  # the nominal one (Table 1 unless a file is named)
    track: TrackParameters
    controller: ControllerParameters  # u_min, u_max, slew_rate_max, fallback_force, ...
    reference: ReferenceParameters
    laws: LawParameters  # design_stiffness, design_delay_ticks, ...


@njit(cache=True)
def _no_restart(consts: np.ndarray, state: np.ndarray, has_u: bool, u_applied: float) -> None:
    """A law without memory to forget."""


@njit(cache=True)
def _no_commit(consts: np.ndarray, state: np.ndarray, u_applied: float) -> None:
    """A law that does not need the limited force."""


def _no_design(setup: LawSetup) -> np.ndarray:
    """A law without constants."""
    return np.zeros(0)


@dataclass(frozen=True)
class LawFile:
    """A law file, loaded and checked against the protocol (the module docstring)."""

    path: str  # as the user named it
    digest: str  # SHA-256 of its text (a campaign point's key holds it)
    needs: frozenset[str]
    state_size: int
    design: Callable[[LawSetup], Any]
    output: Callable[..., Any]
    restart: Callable[..., Any]
    commit: Callable[..., Any]
    #: The chain around the law, compiled (:func:`compiled_chain`; None: a law at Python speed)
    step: Callable[..., Any] | None = None
    step_one: Callable[..., Any] | None = None

    @property
    def compiled(self) -> bool:
        """Whether the law runs compiled into the chain (output, restart and commit are numba's)."""
        return self.step is not None


def refuse(path: str, why: str) -> ParameterError:
    """The one-line refusal of law file ``path``."""
    return ParameterError("law", path, f"a control law file ({PROTOCOL}): {why}")


def file_digest(path: str) -> str:
    """SHA-256 of the text of law file ``path``; ParameterError (one line) when it cannot be read."""
    return user_file.file_digest(path, functools.partial(refuse, path))


#: Loaded files by absolute path: a file is imported once per process (a campaign builds many
#: points of one law; the node builds its law again on a retune).
_LOADED: dict[str, LawFile] = {}


def load_law_file(path: str) -> LawFile:
    """The law of file ``path``, imported from the file (not from ``sys.path``) and checked;
    ParameterError, one line, for a missing file, one that fails to import, one without the
    protocol, and one whose text changed since this process imported it (a law is fixed for a run)."""
    return user_file.load_once(path, _LOADED, "pac_user_law", _check, functools.partial(refuse, path))


def load_law_module(name: str) -> LawFile:
    """The law of module ``name`` (importable, e.g. ``pac_controller.skyhook``), checked against the
    same protocol as a file: how a law joins the registry (``pac_controller.laws.law_module``).
    Its ``path`` is the module's name; its digest that of its source (a packaged law is versioned
    with the package, so a campaign key holds its name only)."""
    loaded = _LOADED.get(name)
    if loaded is None:
        module = importlib.import_module(name)
        source = Path(module.__file__).read_bytes() if module.__file__ else name.encode()
        loaded = _LOADED[name] = _check(name, hashlib.sha256(source).hexdigest(), module)
    return loaded


def _check(path: str, digest: str, module: ModuleType) -> LawFile:
    """The protocol's names of ``module``, checked."""
    if not hasattr(module, "NEEDS"):
        raise refuse(path, "it does not define NEEDS")
    needs = module.NEEDS
    if isinstance(needs, str) or not all(isinstance(n, str) for n in needs):
        raise refuse(path, f"NEEDS = {needs!r} is not a collection of names")
    unknown = sorted(set(needs) - set(ESTIMATE_PARTS))
    if unknown:
        raise refuse(path, f"NEEDS names {', '.join(unknown)}; it may name {', '.join(ESTIMATE_PARTS)}")
    size = getattr(module, "STATE_SIZE", 0)
    if isinstance(size, bool) or not isinstance(size, int) or size < 0:
        raise refuse(path, f"STATE_SIZE = {size!r} is not a whole number >= 0")
    functions = {}
    for name, default in (
        ("design", _no_design),
        ("output", None),
        ("restart", _no_restart),
        ("commit", _no_commit),
    ):
        fn = getattr(module, name, default)
        if fn is None:
            raise refuse(path, f"it does not define {name}")
        if not callable(fn):
            raise refuse(path, f"{name} is not a function")
        functions[name] = fn
    if all(is_jitted(functions[name]) for name in ("restart", "output", "commit")):
        functions["step"], functions["step_one"] = compiled_chain(
            functions["restart"], functions["output"], functions["commit"]
        )
    return LawFile(path, digest, frozenset(needs), size, **functions)


class UserLaw:
    """A law file as a ``controller.Law``: its functions on its constants and memory."""

    mode = "active"

    def __init__(self, law: LawFile, setup: LawSetup) -> None:
        self.file = law
        try:  # its own copy, as flat floats (what the compiled chain takes)
            self.consts = np.array(law.design(setup), dtype=np.float64).reshape(-1)
        except Exception as exc:  # noqa: BLE001 - the user's design failing is a refusal of the file
            raise refuse(law.path, f"design raised {user_file.where(exc, law.path)}") from None
        self.state = np.zeros(law.state_size)
        self.uses_estimate = bool(law.needs & {"z_hat", "theta_hat"})
        self.uses_contact_force = "contact_force_hat" in law.needs
        if law.compiled:
            self._compile()

    def chain_step(
        self,
        params: np.ndarray,
        states: np.ndarray,
        tick: int,
        z_hat: np.ndarray,
        theta_hat: np.ndarray,
        f_hat: float,
    ) -> tuple[float, float, float, float, float, float, int] | None:
        """The compiled law's command through the chain (``Controller.compute``), on the controller's
        records; None for a law at Python speed (the controller calls it between the chain's parts)."""
        if self.file.step_one is None:
            return None
        # A law file reads no actuator force (the chain passes NaN for it).
        return self.file.step_one(
            params, states, self.consts, self.state, tick, z_hat, theta_hat, f_hat, math.nan
        )

    def _compile(self) -> None:
        """Compile the chain with the law's functions now, on a copy of its memory and the types the
        controller passes: a law that does not compile is refused in one line, before any run."""
        params, states = np.zeros(1, CONTROLLER_PARAMS), np.zeros(1, CONTROLLER_STATE)
        for name in ("dt", "u_max", "slew_rate_max"):  # a period and limits that are numbers
            params[0][name] = 1.0
        params[0]["u_min"] = -1.0
        new_state(states)
        step_one = self.file.step_one
        assert step_one is not None
        try:
            step_one(
                params, states, self.consts.copy(), self.state.copy(), 0, np.zeros(4), np.zeros(3), 0.0, 0.0
            )
        except NumbaError as exc:
            raise refuse(self.file.path, f"its njit functions do not compile: {_numba_reason(exc)}") from None
        except Exception:  # noqa: BLE001 - compiled; what it raised on these made-up inputs is no refusal
            pass

    def __deepcopy__(self, memo: dict) -> UserLaw:
        """A twin with its own memory, sharing the file's functions (``Controller.warm_up``)."""
        twin = copy.copy(self)
        twin.consts, twin.state = self.consts.copy(), self.state.copy()
        return twin

    def restart(self, u_applied: float | None) -> None:
        u = 0.0 if u_applied is None else float(u_applied)
        self.file.restart(self.consts, self.state, u_applied is not None, u)

    def output(
        self,
        tick: int,
        t: float,
        f_r: np.ndarray,
        z_hat: np.ndarray,
        theta_hat: np.ndarray,
        contact_force_hat: float = math.nan,
    ) -> tuple[float, tuple[float, float, float]]:
        """The law's demand; no law-specific errors (zeros in ``tracking_error``)."""
        u = self.file.output(
            self.consts, self.state, float(t), f_r, z_hat, theta_hat, float(contact_force_hat)
        )
        return float(u), (0.0, 0.0, 0.0)

    def commit(self, tick: int, u_applied: float) -> None:
        self.file.commit(self.consts, self.state, float(u_applied))


def _numba_reason(exc: NumbaError) -> str:
    """The line of a numba error that says what is wrong (not its "Failed in ... pipeline" frame)."""
    lines = [line.strip() for line in str(exc).splitlines() if line.strip()]
    told = [line for line in lines if not line.startswith(("Failed in", "During:", "File ", "^"))]
    return (told or lines or [type(exc).__name__])[0]


@njit(cache=True)
def _user_mode(p, s) -> int:
    """The mode code of a user law's commands: always active."""
    return ACTIVE


def compiled_chain(restart: Callable, output: Callable, commit: Callable) -> tuple[Callable, Callable]:
    """The safety chain around a law file's compiled functions (``kernels.safety_chain``): its
    ``controller_step`` (the law's constants as ``table``, its memory as ``memory``) and that step
    on the records of 1-element arrays (as ``kernels.step_one``, for ``Controller.compute``)."""

    @njit(error_model="numpy")
    def restart_law(p, s, consts, state, has_u: bool, u_applied: float) -> None:
        restart(consts, state, has_u, u_applied)

    @njit(error_model="numpy")
    def law_output(
        p, s, consts, state, tick: int, t: float, f_r, z_hat, theta_hat, f_hat: float, measured: float
    ):
        return float(output(consts, state, t, f_r, z_hat, theta_hat, f_hat)), 0.0, 0.0, 0.0

    @njit(error_model="numpy")
    def commit_law(p, s, consts, state, tick: int, u_applied: float) -> None:
        commit(consts, state, u_applied)

    step = safety_chain(restart_law, law_output, _user_mode, commit_law)

    @njit(error_model="numpy")
    def step_one(params, states, consts, state, tick: int, z_hat, theta_hat, f_hat: float, measured: float):
        return step(params[0], states[0], consts, state, tick, z_hat, theta_hat, f_hat, measured)

    return step, step_one
