"""Which parts of a run fit together: what a run derives from the parts it is given, and what it
refuses before it starts.

A law states what it needs of the estimate besides z_hat (``pac_controller.laws.LAWS``:
``needs``; a fixed-gain law, pid or lqr, needs what its form of F_hat needs,
``FORCE_ESTIMATE_NEEDS``) and the observer it runs on when none is named (``observer``); an
observer states what it gives (``pac_observer.observers.OBSERVERS``: ``gives``). From them:

- **derived**, where the user named nothing: ``law:=line_adaptive`` alone runs on the observer it
  needs (``observer:=contact_force``), or on the one that stands in for it where the run's sensors
  have what that one reads (``ObserverEntry.on_richer_sensors``: ``head_balance`` with a head
  accelerometer); a law that takes a line layout (``LawEntry.line_layout``) is told the design
  layout of the whole line the plant runs; a law that names its passive run-in
  (``LawEntry.runin_spans``), on a pantograph with others ahead of it, runs passive until the wave
  of the farthest one ahead has reached it (where they are active too, ``all_pantographs_active``,
  until their learning has settled: ``LawEntry.settle_spans``), and takes its design for that
  position (``LawEntry.behind_another``), and on one with another active one behind it its design
  for that (``LawEntry.ahead_of_active``); a law's design for an actuator as hardware
  (``LawEntry.actuator_design``: from the actuator's lag and a span's passing time) where the
  actuator is one; a fixed-gain law feeds back F_hat in the first form its observer gives
  (``force_estimate``: k_hat z1 on the paper's observer, the filter's own F_hat on
  ``observer:=contact_force``); on the FE line (``catenary_model:=fe``) the observer and the
  controller are told the span of the line the plant runs (its catenary file's mean span), not the
  65 m default of the lumped model, and a fixed-gain law is designed at the line's
  equivalent stiffness (``design_stiffness``: its mean static stiffness over a period of the design
  spans, ``pac_plant.fe_plant.equivalent_contact_stiffness``), not the lumped model's k0; an
  actuator as hardware works about the run's reference (``actuator_static_force`` =
  ``force_amplitude``) and the controller is told its range (``u_min``, ``u_max`` = that force -+
  the range);
- **refused**, with one line naming both parts and what would fit: a law that needs what its
  observer does not give (``adaptive_backstepping`` on ``observer:=contact_force`` would run on
  theta_hat = 0; so would ``pid`` told ``force_estimate:=k_hat_z1`` there), and an observer that
  reads a sensor channel the run's sensors lack (``ObserverEntry.reads``).

Every offline entry point applies both: ``simulate`` and campaign points derive
(:func:`derive`), and :func:`check_pair` runs wherever the cores are built
(``closed_loop.build_cores``: simulate, the batch, campaigns, lock step), so no path runs a
refused pair.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any

from pac_common.parameters import ParameterError

from . import scenario_file

if TYPE_CHECKING:
    from pac_controller.laws import LawEntry


class CompositionError(ParameterError):
    """Two parts of a run that cannot work together (one line: both parts, and what would fit)."""

    def __init__(self, name: str, value: Any, message: str) -> None:
        self.name = name
        self.value = value
        self.allowed = message
        ValueError.__init__(self, message)


def actuator_static_force(given: Mapping[str, Any]) -> float | None:
    """The static force an actuator as hardware works about when ``given`` names none: the run's
    force reference (a passive law commands it; its default is the reference's default); None for
    the ideal actuator or a value given."""
    from pac_controller.parameters import ReferenceParameters

    if str(given.get("actuator", "ideal")) == "ideal" or "actuator_static_force" in given:
        return None
    return float(given.get("force_amplitude", ReferenceParameters().force_amplitude))


def derive(
    values: Mapping[str, Any], defaults: Mapping[str, Any] | None = None
) -> tuple[dict[str, Any], list[str]]:
    """``values`` (flat parameter names) with what the named parts imply where the user named
    nothing, and one line per derived value (for a log). ``defaults``: values the caller holds
    elsewhere (the rig launcher: the observer node's parameters), consulted like ``values``."""
    from pac_controller.laws import FORCE_ESTIMATE_NEEDS, LAWS
    from pac_controller.parameters import ControllerParameters, LawParameters
    from pac_observer.choice import observer_entry
    from pac_observer.observers import OBSERVERS
    from pac_observer.parameters import ObserverParameters
    from pac_plant.parameters import PlantOptions
    from pac_plant.plants import plant_kind

    # A scenario file's parts count as named (its values are consulted, not copied: ``scenario``
    # stays in the result, which the cores expand again).
    expanded, notes = scenario_file.expand(values)
    given = {**(defaults or {}), **expanded}
    out = dict(values)
    law = str(given.get("law", ControllerParameters().law))
    entry = LAWS.get(law)
    if "observer" not in given and entry is not None and entry.observer is not None:
        out["observer"] = entry.observer
        why = f"what law {law} runs on"
        richer = OBSERVERS[entry.observer].on_richer_sensors
        if richer is not None and not _sensors_lack(OBSERVERS[richer].reads, given):
            read = " and ".join(what for _, what in OBSERVERS[richer].reads)
            out["observer"], why = richer, f"what law {law} runs on, where the sensors have {read}"
        notes.append(f"observer:={out['observer']} ({why})")
    observer = str(out.get("observer", given.get("observer", ObserverParameters().observer)))
    plant_defaults = PlantOptions()  # one construction: it reads the default catenary file
    fe_line = plant_kind(str(given.get("catenary_model", plant_defaults.catenary_model))).line_from_file
    catenary = str(given.get("catenary", plant_defaults.catenary))
    known = observer in OBSERVERS or observer.endswith(".py")
    if entry is not None and entry.fixed_gain and "force_estimate" not in given and known:
        gives = observer_entry(observer).gives
        form = next((f for f, needs in FORCE_ESTIMATE_NEEDS.items() if needs <= gives), None)
        if form is not None and form != LawParameters().force_estimate:
            out["force_estimate"] = form
            notes.append(f"force_estimate:={form} (the F_hat observer {observer} gives law {law})")
    if entry is not None and entry.fixed_gain and fe_line:
        notes += _fe_line_design(entry, law, given, out, catenary)
    if fe_line and "span_length" not in given:
        from pac_plant.catenary.catenary_file import load_catenary

        out["span_length"] = load_catenary(catenary).data.span
        notes.append(f"span_length:={out['span_length']:g} (the mean span of the FE line {catenary})")
    if fe_line and entry is not None and entry.line_layout and "line_supports" not in given:
        notes += _line_layout(given, out, catenary)
    if fe_line and entry is not None and (entry.runin_spans is not None or entry.behind_another):
        notes += _behind_another(entry, law, given, out, catenary, _train(given, plant_defaults))
    static_force = actuator_static_force(given)
    if static_force is not None:
        out["actuator_static_force"] = static_force
        notes.append(
            f"actuator_static_force:={static_force:g} (the run's force_amplitude: the "
            f"{given['actuator']} actuator's range is about it)"
        )
    actuator = str(given.get("actuator", "ideal"))
    if actuator != "ideal" and "u_min" not in given and "u_max" not in given:
        notes.extend(_actuator_limits(actuator, {**given, **out}, out))
    ahead: dict[str, Any] = {}  # the design ahead of an active one wins over the actuator's
    if fe_line and entry is not None and entry.ahead_of_active:
        notes += _ahead_of_active(entry, law, given, ahead, _train(given, plant_defaults))
        out.update(ahead)
    if entry is not None and entry.actuator_design is not None and actuator != "ideal":
        notes += _actuator_design(entry.actuator_design, law, actuator, {**given, **ahead}, out)
    return out, notes


#: A run's train (``_train``): each pantograph's distance behind the first, the controlled one's
#: index, and whether every pantograph is active.
Train = tuple[list[float], int, bool]


def _train(given: Mapping[str, Any], defaults: Any) -> Train:
    """The train ``given`` names, the plant's ``defaults`` (a ``PlantOptions``) for what it does not."""
    return (
        [float(s) for s in given.get("pantographs", defaults.pantographs)],
        int(given.get("controlled_pantograph", defaults.controlled_pantograph)),
        bool(given.get("all_pantographs_active", defaults.all_pantographs_active)),
    )


def _ahead_of_active(
    entry: LawEntry, law: str, given: Mapping[str, Any], out: dict[str, Any], train: Train
) -> list[str]:
    """On a pantograph with another active one behind it (``all_pantographs_active``), into ``out``
    where the user names them not: the law's design for that place (``LawEntry.ahead_of_active``)."""
    spacings, controlled, all_active = train
    if not all_active:
        return []
    if not 0 <= controlled < len(spacings) - 1:
        return []  # none behind it (or refused by name where the plant is built)
    why = f"law {law}'s design for a pantograph with another active one behind it"
    return _design_values(entry.ahead_of_active, given, out, why)


def _actuator_design(
    design: Callable[[float, float], tuple[tuple[str, float], ...]],
    law: str,
    actuator: str,
    given: Mapping[str, Any],
    out: dict[str, Any],
) -> list[str]:
    """A law's design for an actuator as hardware (``LawEntry.actuator_design``), into ``out`` where
    the user named nothing: from the actuator's lag plus delay and the time the run's span (the FE
    line's mean span where derived) takes to pass at the run's speed."""
    from pac_model.parameters import TrackParameters
    from pac_plant.hardware.actuators import actuator_model

    model = actuator_model(actuator)
    track = TrackParameters()
    span = float(out.get("span_length", given.get("span_length", track.span_length)))
    speed = float(given.get("speed_kmh", track.speed_kmh)) / 3.6
    values = design(model.time_constant + model.delay, span / speed)
    return _design_values(values, given, out, f"law {law}'s design for the {actuator} actuator")


def _design_values(
    values: tuple[tuple[str, object], ...], given: Mapping[str, Any], out: dict[str, Any], why: str
) -> list[str]:
    """A law's design values, (parameter, value) pairs, into ``out`` where the user named nothing,
    and one note each that says ``why``."""
    notes = []
    for name, value in values:
        if name not in given:
            out[name] = value
            shown = f"{value:g}" if isinstance(value, int | float) else value
            notes.append(f"{name}:={shown} ({why})")
    return notes


def _fe_line_design(
    entry: LawEntry, law: str, given: Mapping[str, Any], out: dict[str, Any], catenary: str
) -> list[str]:
    """A fixed-gain law's design for the FE line, into ``out`` where the user named nothing: its
    stiffness (the line's equivalent one), then what the law derives at it (``LawEntry.fe_line``)."""
    from pac_common.parameters import RateParameters
    from pac_controller.parameters import LawParameters
    from pac_model.parameters import PantographParameters
    from pac_plant.fe_plant import equivalent_contact_stiffness
    from pac_plant.parameters import PlantOptions

    notes = []
    if "design_stiffness" not in given:
        element_size = float(given.get("fe_element_size", PlantOptions().fe_element_size))
        # To 0.1 N/m: a value that does not move with the last bits of a sum (campaign keys hash it).
        out["design_stiffness"] = round(equivalent_contact_stiffness(catenary, element_size), 1)
        notes.append(
            f"design_stiffness:={out['design_stiffness']:g} (the mean static stiffness of the FE line "
            f"{catenary})"
        )
    if entry.fe_line is not None:
        run = {**given, **out}  # the run's parameters as its scenario will hold them
        laws = LawParameters.from_mapping(run)
        pantograph, dt = (
            PantographParameters.from_mapping(run),
            RateParameters.from_mapping(run).sample_period,
        )
        for name, value in entry.fe_line(pantograph, laws, dt).items():
            if name not in given and value != getattr(laws, name):
                out[name] = value
                notes.append(f"{name}:={value:g} (law {law}'s design for the FE line)")
    return notes


def _sensors_lack(reads: tuple[tuple[str, str], ...], given: Mapping[str, Any]) -> list[str]:
    """What of the channels ``reads`` ((channel, what it is) pairs) the run's sensor suite lacks."""
    from pac_plant.hardware.sensors import SENSORS
    from pac_plant.parameters import PlantOptions

    suite = SENSORS.get(str(given.get("sensors", PlantOptions().sensors)))
    return [what for channel, what in reads if suite is None or getattr(suite, channel) is None]


def _line_layout(given: Mapping[str, Any], out: dict[str, Any], catenary: str) -> list[str]:
    """A law told the design layout of a whole line (the line map a train carries: its
    supports, not the drawn deviation) and where its contact point starts on it (the plant's start:
    the first interior support with every pantograph on the line, ``pac_plant.fe_plant``), into
    ``out``; nothing on a period (the law learns over the nominal span's period there)."""
    import numpy as np

    from pac_plant.catenary.catenary_file import load_catenary
    from pac_plant.parameters import PlantOptions

    defaults = PlantOptions()
    seed = int(given.get("line_seed", defaults.line_seed))
    drawn = load_catenary(catenary)
    supports = drawn.design_supports(None if seed < 0 else seed)
    if supports is None:
        return []
    overlaps = drawn.design_overlaps(None if seed < 0 else seed)
    spacings = tuple(float(s) for s in given.get("pantographs", defaults.pantographs))
    controlled = int(given.get("controlled_pantograph", defaults.controlled_pantograph))
    start = max(1, int(np.searchsorted(supports, spacings[-1])))
    # To 1 mm: values that do not move with the last bits of a sum (campaign keys hash them).
    out["line_supports"] = tuple(round(float(x), 3) for x in supports)
    out["line_position_start"] = round(float(supports[start]) - spacings[controlled], 3)
    notes = [
        f"line_supports:=({len(supports)} supports of the design layout of {catenary}, line seed {seed}), "
        f"line_position_start:={out['line_position_start']:g} (where the contact point starts)"
    ]
    if len(overlaps) and "line_overlaps" not in given:
        out["line_overlaps"] = tuple(round(float(x), 3) for x in overlaps.ravel())
        notes.append(f"line_overlaps:=({len(overlaps)} overlaps of its tension sections)")
    return notes


def _behind_another(
    entry: LawEntry, law: str, given: Mapping[str, Any], out: dict[str, Any], catenary: str, train: Train
) -> list[str]:
    """On a pantograph with others ahead of it on the train, into ``out`` where the user names
    them not: the law's passive run-in (``LawEntry.runin_spans``) lengthened by the spans it runs
    before the wave of the farthest one ahead reaches it, since the law's guard measures its
    passive reference in the run-in and should measure it on the wire the law will act on; and the
    law's design for a pantograph behind another (``LawEntry.behind_another``). Every pantograph is
    set down at once; the wave of one d ahead runs back along the contact wire at c = sqrt(T / rho)
    over ground while this one runs forward at v, so it arrives after d / (c + v). Nothing for a
    pantograph with none ahead: what one behind it sends forward closes in at c - v only
    (docs/realistic_scenario.md, "Two pantographs"). Where the ones ahead are active too
    (``all_pantographs_active``), their wave changes while their laws learn: the run-in waits also
    for the spans of that learning's transient (``LawEntry.settle_spans``), which the identification
    of this law's own responses would otherwise take for its own doing (docs/laws.md)."""
    import math

    from pac_controller.parameters import LawParameters
    from pac_model.parameters import TrackParameters
    from pac_plant.catenary.catenary_file import load_catenary

    spacings, controlled, all_active = train
    if not 0 <= controlled < len(spacings):
        return []  # refused by name where the plant is built
    ahead = max((spacings[controlled] - s for s in spacings if s < spacings[controlled]), default=0.0)
    if ahead <= 0.0:
        return []
    notes = []
    name = entry.runin_spans
    if name is not None and name not in given:
        line = load_catenary(catenary).data
        v = float(given.get("speed_kmh", TrackParameters().speed_kmh)) / 3.6
        arrival = ahead / (line.contact.wave_speed + v)
        spans = math.ceil(v * arrival / line.span)
        settle = entry.settle_spans if all_active else None
        learning = int(given.get(settle, getattr(LawParameters(), settle))) if settle else 0
        out[name] = int(getattr(LawParameters(), name)) + learning + spans
        why = f"{learning} spans of its learning and " if learning else ""
        notes.append(
            f"{name}:={out[name]} (law {law}'s run-in and {learning + spans} spans more: {why}the wave "
            f"of the pantograph {ahead:g} m ahead reaches this one {arrival:.2f} s after the start)"
        )
    why = f"law {law}'s design for a pantograph {ahead:g} m behind another"
    return notes + _design_values(entry.behind_another, given, out, why)


def _actuator_limits(actuator: str, given: Mapping[str, Any], out: dict[str, Any]) -> list[str]:
    """The controller told its actuator's range: u_min, u_max = F0 -+ R (F0 the actuator's static
    force), so that a command beyond it is clipped where the law sees it (its anti-windup learns
    on what was applied, its guard counts the clipped share) instead of downstream, where the law
    would keep asking for a force it never gets (docs/laws.md)."""
    from pac_plant.hardware.actuators import ACTUATORS

    reach = ACTUATORS[actuator].force_range
    if not reach < float("inf"):
        return []
    from pac_controller.parameters import ControllerParameters

    static = float(given["actuator_static_force"])
    out["u_min"], out["u_max"] = static - reach, static + reach
    lines = [f"u_min:={out['u_min']:g}, u_max:={out['u_max']:g} (the {actuator} actuator's range)"]
    fallback = float(given.get("fallback_force", ControllerParameters().fallback_force))
    if "fallback_force" not in given and not out["u_min"] <= fallback <= out["u_max"]:
        out["fallback_force"] = min(max(fallback, out["u_min"]), out["u_max"])
        lines.append(f"fallback_force:={out['fallback_force']:g} (within the actuator's range)")
    return lines


def check_pair(
    law: str, observer: str, force_estimate: str | None = None, sensors: str | None = None
) -> None:
    """Refuse (CompositionError) law ``law`` on observer ``observer`` if it needs what that one
    does not give (a fixed-gain law: with F_hat in the form ``force_estimate``, None: the
    parameter's default); one line naming both and what would fit. A user's law file and observer
    file are loaded here (each refused in one line if it cannot be). ``sensors`` (the plant's
    suite; None: not checked): it must have what the observer reads (``ObserverEntry.reads``)."""
    from pac_observer.choice import observer_entry
    from pac_observer.observers import OBSERVERS

    chosen = observer_entry(observer)
    lacking = [] if sensors is None else _sensors_lack(chosen.reads, {"sensors": sensors})
    if lacking:
        from pac_plant.hardware.sensors import SENSORS

        reads = chosen.reads
        with_them = [name for name in SENSORS if not _sensors_lack(reads, {"sensors": name})]
        others = [
            name
            for name, other in OBSERVERS.items()
            if name != observer
            and other.gives >= chosen.gives
            and not _sensors_lack(other.reads, {"sensors": sensors})
        ]
        raise CompositionError(
            "observer",
            observer,
            f"observer '{observer}' reads {' and '.join(lacking)}, which sensors '{sensors}' do not "
            f"have: sensors:={' or '.join(with_them)}, or observer:={' or '.join(others)}",
        )
    from pac_controller.laws import FORCE_ESTIMATE_NEEDS, LAWS, law_entry
    from pac_controller.parameters import LawParameters

    form = force_estimate or LawParameters().force_estimate
    entry = law_entry(law)
    needs, gives = entry.needs_of(form), chosen.gives
    missing = needs - gives
    if not missing:
        return
    fitting_laws = [name for name, other in LAWS.items() if other.needs_of(form) <= gives]
    fitting_observers = [name for name, other in OBSERVERS.items() if needs <= other.gives]
    fitting_forms = (
        [f for f in FORCE_ESTIMATE_NEEDS if entry.needs_of(f) <= gives] if entry.fixed_gain else []
    )
    with_form = f", or force_estimate:={' or '.join(fitting_forms)}" if fitting_forms else ""
    raise CompositionError(
        "law",
        law,
        f"law '{law}' needs {', '.join(sorted(missing))}, which observer '{observer}' does not give: "
        f"run it on observer:={' or '.join(fitting_observers)}{with_form}, or on observer '{observer}' "
        f"one of law:={', '.join(fitting_laws)}",
    )
