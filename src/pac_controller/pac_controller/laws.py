"""The control laws by name (``law`` parameter) and the controller that runs one of them.

| name | core | uses |
|---|---|---|
| adaptive_backstepping | backstepping.BacksteppingController | z_hat, theta_hat (eq. (43)) |
| backstepping_known | backstepping.KnownThetaBackstepping | z_hat, the true theta (oracle) |
| pid | pid.PidLaw (gains from pid.design_pid) | F_hat in the form force_estimate |
| lqr | lqr.LqrLaw (gains from lqr.design_lqr) | z_hat, F_hat in the form force_estimate |
| passive | passive.PassiveLaw | nothing (u = F_r) |
| line_adaptive | line_adaptive.LineAdaptiveLaw | F_hat of the estimate (observer:=contact_force) |

Every law runs inside the same :class:`pac_controller.controller.Controller`
(reference, fallback, slew limit, saturation).  Equations: each module's docstring
and docs/laws.md.  ``law`` may also name a user's Python file (``my_law.py``): its law
(:mod:`pac_controller.user_law`) runs in the same controller (:func:`law_entry`).
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from importlib.metadata import entry_points

from pac_common.parameters import ParameterError
from pac_model.parameters import CatenaryParameters, PantographParameters, TrackParameters

from .backstepping import BacksteppingController, KnownThetaBackstepping
from .controller import Controller, Law
from .line_adaptive import DESIGN_AHEAD_OF_ACTIVE, DESIGN_BEHIND_ANOTHER, LineAdaptiveLaw, design_for_actuator
from .lqr import LqrLaw, design_lqr
from .parameters import FORCE_ESTIMATES, ControllerParameters, LawParameters, ReferenceParameters
from .passive import PassiveLaw
from .pid import PidLaw, design_pid, least_derivative_filter
from .user_law import LawFile, LawSetup, UserLaw, load_law_file, load_law_module, refuse

#: Laws that need the catenary parameters (k0, alpha, beta): the controller is told them.
NEEDS_CATENARY = frozenset({"backstepping_known"})


def _adaptive(pantograph, track, params, reference, laws, catenary, dt) -> Law:
    return BacksteppingController(pantograph, track, params, reference, dt)


def _known(pantograph, track, params, reference, laws, catenary, dt) -> Law:
    return KnownThetaBackstepping(BacksteppingController(pantograph, track, params, reference, dt), catenary)


def _pid(pantograph, track, params, reference, laws, catenary, dt) -> Law:
    return PidLaw(design_pid(pantograph, laws, dt), track, dt, laws.force_estimate)


def _lqr(pantograph, track, params, reference, laws, catenary, dt) -> Law:
    return LqrLaw(
        design_lqr(pantograph, laws, dt), pantograph, track, dt, laws.lqr_integral_time, laws.force_estimate
    )


def _passive(pantograph, track, params, reference, laws, catenary, dt) -> Law:
    return PassiveLaw()


def _line_adaptive(pantograph, track, params, reference, laws, catenary, dt) -> Law:
    return LineAdaptiveLaw(track, laws, dt, pantograph)


THETA = frozenset({"theta_hat"})

#: What each form of F_hat a fixed-gain law feeds back (``force_estimate``) needs of the estimate:
#: k_hat z_hat_1 is built from theta_hat (eqs. (6), (8)); the estimate's own F_hat is its
#: contact_force_hat. In this order a run derives the form from its observer (pac_rig.composition):
#: the paper's first, so a law on the paper's observer runs as it always has.
FORCE_ESTIMATE_NEEDS: dict[str, frozenset[str]] = {
    "k_hat_z1": THETA,
    "contact_force_hat": frozenset({"contact_force_hat"}),
}
assert tuple(FORCE_ESTIMATE_NEEDS) == FORCE_ESTIMATES, "every form of F_hat states what it needs"


@dataclass(frozen=True)
class LawEntry:
    """One law of the registry: its builder, what it needs of the estimate besides z_hat
    (pac_observer.parameters.OBSERVER_GIVES names what each observer gives), the observer a run
    gives it when none is named (pac_rig.composition), and whether it is a fixed-gain law
    (``fixed_gain``: gains designed on the linear contact model at ``design_stiffness``, feedback
    on F_hat in the form ``force_estimate``, which adds that form's needs)."""

    build: Callable[..., Law]
    needs: frozenset[str] = frozenset()
    observer: str | None = None  # None: the default observer
    fixed_gain: bool = False
    #: A fixed-gain law's design values on the FE line besides its stiffness, from the pantograph,
    #: the design (LawParameters at the line's stiffness) and the period (docs/laws.md).
    fe_line: Callable[[PantographParameters, LawParameters, float], dict[str, float]] | None = None
    #: Whether the law has a compiled form (the compiled loop and the batch run it): pac's kernel
    #: laws, and a law module or file whose output, restart and commit are numba's.
    compiled: bool = True
    #: A law of the file protocol: its module's name (a law module) or its file's path; None: a kernel law.
    source: str | None = None
    #: A kernel law's compiled parts: the module of its four functions (kernel_common), which the
    #: generated ``law_dispatch`` calls under the code the registry's order gives; None: not one.
    kernel: str | None = None
    #: Whether the law is told the design layout of a whole line (``line_supports``: the supports an
    #: infrastructure manager publishes, not the drawn deviation; ``line_position_start``: where its
    #: contact point starts), which the run derives from the line the plant runs (pac_rig.composition).
    line_layout: bool = False
    #: The law's design values, (parameter, value) pairs, where the actuator is hardware (limited range
    #: and rate), from the actuator's lag plus delay [s] and the time a span takes to pass [s]; each
    #: derived where the user names it not. None: the law's defaults serve any actuator.
    actuator_design: Callable[[float, float], tuple[tuple[str, float], ...]] | None = None
    #: The law's parameter that holds its passive run-in in spans (where its guard measures the
    #: passive reference), if it has one: on a train, a pantograph with another ahead of it runs
    #: passive until that one's wave has reached it (derived by pac_rig.composition).
    runin_spans: str | None = None
    #: The law's parameter that holds how many learning spans its transient lasts (its guard waits
    #: them out), if it has one: behind another active pantograph, the run-in also waits until that
    #: one's learning has settled and its wave has come (pac_rig.composition).
    settle_spans: str | None = None
    #: The law's design values, (parameter, value) pairs, on a pantograph with others ahead of it on
    #: the train, where the wave it meets from them makes its spans differ; each derived where the
    #: user names it not (pac_rig.composition). Empty: the law's defaults serve either position.
    behind_another: tuple[tuple[str, object], ...] = ()
    #: The law's design values on a pantograph with another active one behind it (both of a pair
    #: active, ``all_pantographs_active``), each derived where the user names it not.
    ahead_of_active: tuple[tuple[str, object], ...] = ()

    def needs_of(self, force_estimate: str) -> frozenset[str]:
        """What the law needs of the estimate besides z_hat when F_hat is fed back in the form
        ``force_estimate`` (which only a fixed-gain law reads)."""
        return self.needs | FORCE_ESTIMATE_NEEDS[force_estimate] if self.fixed_gain else self.needs


#: lqr_force_scale on the FE line: judgement, from a scan on the design line at 300 km/h (docs/laws.md,
#: "Fixed-gain laws on the FE line"); 1 N, the lumped design's, leaves the loop unstable there.
FE_LINE_LQR_FORCE_SCALE = 3.0


#: Crossovers [rad/s] tried below pid_bandwidth when no derivative filter gives a stable design there.
FE_LINE_PID_CROSSOVERS = (18.0, 15.0, 12.0, 10.0, 8.0, 6.0, 5.0, 4.0, 3.0, 2.0)


def _pid_on_fe_line(pantograph: PantographParameters, laws: LawParameters, dt: float) -> dict[str, float]:
    """The least derivative filter ratio the crossover rule allows (pid.least_derivative_filter) at
    pid_bandwidth; where none does (on the realistic scenario's identified 3-mass nominal the sampled
    loop at 21 rad/s is unstable for every ratio), the highest of FE_LINE_PID_CROSSOVERS below it
    where one does: a design that runs rather than a run refused at the build."""
    design = {name: getattr(laws, name) for name in PID_DESIGN_FIELDS}
    return dict(_pid_design_on_fe_line(pantograph, dataclasses.replace(LawParameters(), **design), dt))


#: What pid.design_pid reads of the law parameters: the cache's key holds these and no other.
PID_DESIGN_FIELDS = tuple(spec.name for spec in LawParameters.specs() if spec.name.startswith("pid_")) + (
    "design_delay_ticks",
    "design_stiffness",
)


@functools.lru_cache(maxsize=64)
def _pid_design_on_fe_line(
    pantograph: PantographParameters, laws: LawParameters, dt: float
) -> tuple[tuple[str, float], ...]:
    # Cached: the search designs the loop up to a few hundred times (0.4 s), and a campaign derives
    # it for every point of a grid whose lines differ but whose pantograph and law do not.
    for crossover in (laws.pid_bandwidth, *(w for w in FE_LINE_PID_CROSSOVERS if w < laws.pid_bandwidth)):
        n = least_derivative_filter(pantograph, dataclasses.replace(laws, pid_bandwidth=crossover), dt)
        if n is not None:
            return (("pid_derivative_filter", n), ("pid_bandwidth", crossover))
    return ()


def _lqr_on_fe_line(pantograph: PantographParameters, laws: LawParameters, dt: float) -> dict[str, float]:
    return {"lqr_force_scale": FE_LINE_LQR_FORCE_SCALE}


def _user(law: LawFile, pantograph, track, params, reference, laws, catenary, dt) -> Law:
    return UserLaw(law, LawSetup(dt, pantograph, track, params, reference, laws))


def law_module(module: str, observer: str | None = None) -> LawEntry:
    """The registry entry of a law module: a module of the law-file protocol (user_law's
    docstring, docs/laws.md "Your own law") shipped with the package. A new law is that module
    and one line in :data:`LAWS`; the parameter's choices, the composition rules, the loop, the
    batch, campaigns and the per-law tests read the registry. Its compiled chain is a closure
    (compiled once per process, as a user's compiled file; not in numba's disk cache)."""
    return _entry(load_law_module(module), observer)


def _entry(law: LawFile, observer: str | None = None) -> LawEntry:
    """A law of the file protocol (a module or a user's file) as an entry of the registry."""
    build = functools.partial(_user, law)
    return LawEntry(build, law.needs - {"z_hat"}, observer, compiled=law.compiled, source=law.path)


LAWS: dict[str, LawEntry] = {
    "adaptive_backstepping": LawEntry(_adaptive, THETA, kernel="pac_controller.backstepping_kernels"),
    # told the true theta: z_hat only
    "backstepping_known": LawEntry(_known, kernel="pac_controller.backstepping_kernels"),
    "pid": LawEntry(_pid, fixed_gain=True, fe_line=_pid_on_fe_line, kernel="pac_controller.pid_kernels"),
    "lqr": LawEntry(_lqr, fixed_gain=True, fe_line=_lqr_on_fe_line, kernel="pac_controller.lqr_kernels"),
    "passive": LawEntry(_passive, kernel="pac_controller.passive_kernels"),
    "line_adaptive": LawEntry(
        _line_adaptive,
        frozenset({"contact_force_hat"}),
        observer="contact_force",
        kernel="pac_controller.line_adaptive_kernels",
        line_layout=True,
        actuator_design=design_for_actuator,
        runin_spans="line_runin_spans",
        settle_spans="line_guard_spans",
        behind_another=DESIGN_BEHIND_ANOTHER,
        ahead_of_active=DESIGN_AHEAD_OF_ACTIVE,
    ),
    "skyhook": law_module("pac_controller.skyhook"),
}


#: The entry-point group by which an installed distribution adds laws: ``name = module``, the
#: module written to the law-file protocol (docs/laws.md, "A law from another package").
ENTRY_POINT_GROUP = "pac.laws"


def _refused(message: ParameterError) -> Callable[..., Law]:
    def build(*_: object) -> Law:
        raise message

    return build


def installed_laws(registered: Mapping[str, LawEntry]) -> dict[str, LawEntry]:
    """The laws other installed distributions add (entry points of :data:`ENTRY_POINT_GROUP`), by
    name. A name already ``registered`` stays pac's (the entry point is not read). An entry point
    that cannot be loaded (no such module, a module off the protocol) is still a name: choosing it
    is refused in one line, and every other law runs as before."""
    out: dict[str, LawEntry] = {}
    for point in sorted(entry_points(group=ENTRY_POINT_GROUP), key=lambda ep: ep.name):
        if point.name in registered or point.name in out:
            continue
        if ":" in point.value:
            error = refuse(point.value, "an entry point of pac.laws names a module, not an attribute")
        else:
            try:
                out[point.name] = law_module(point.value)
                continue
            except ParameterError as exc:  # a module off the protocol: its own one line
                error = exc
            except Exception as exc:  # noqa: BLE001 - whatever importing the module raises is its refusal
                error = refuse(point.value, f"importing it raised {type(exc).__name__}: {exc}")
        out[point.name] = LawEntry(_refused(error), compiled=False, source=point.value)
    return out


LAWS.update(installed_laws(LAWS))


def law_entry(name: str) -> LawEntry:
    """The entry of law ``name``: the registry's, or that of a user's law file (a path ending in
    .py, loaded from the file: ParameterError in one line when it cannot be)."""
    if name in LAWS:
        return LAWS[name]
    return _entry(load_law_file(name))


def make_law(
    name: str,
    pantograph: PantographParameters,
    track: TrackParameters,
    params: ControllerParameters,
    reference: ReferenceParameters,
    sample_period: float,
    laws: LawParameters | None = None,
    catenary: CatenaryParameters | None = None,
) -> Law:
    """The core of law ``name``; raises ParameterError when its design fails (pid, lqr)."""
    if name in NEEDS_CATENARY and catenary is None:
        raise ValueError(f"law {name} needs the catenary parameters (k0, alpha, beta)")
    build = law_entry(name).build
    return build(pantograph, track, params, reference, laws or LawParameters(), catenary, sample_period)


def make_controller(
    pantograph: PantographParameters,
    track: TrackParameters,
    params: ControllerParameters,
    reference: ReferenceParameters,
    sample_period: float,
    laws: LawParameters | None = None,
    catenary: CatenaryParameters | None = None,
    controller_class: type[Controller] = Controller,
) -> Controller:
    """The controller running ``params.effective_law`` (``law``, or passive by the deprecated ``mode``)."""
    name = params.effective_law
    law = make_law(name, pantograph, track, params, reference, sample_period, laws, catenary)
    return controller_class(law, params, reference, sample_period, name=name)
