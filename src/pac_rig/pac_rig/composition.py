"""Which parts of a run fit together: what a run derives from the parts it is given, and what it
refuses before it starts.

A law states what it needs of the estimate besides z_hat (``pac_controller.laws.LAWS``:
``needs``) and the observer it runs on when none is named (``observer``); an observer states what
it gives (``pac_observer.parameters.OBSERVER_GIVES``). From them:

- **derived**, where the user named nothing: ``law:=line_adaptive`` alone runs on the observer it
  needs (``observer:=contact_force``); on the FE line (``catenary_model:=fe``) the observer and
  the controller are told the span of the line the plant runs (its catenary file's mean span),
  not the 65 m default of the lumped model; an actuator as hardware works about the run's
  reference (``actuator_static_force`` = ``force_amplitude``) and the controller is told its
  range (``u_min``, ``u_max`` = that force -+ the range);
- **refused**, with one line naming both parts and what would fit: a law that needs what its
  observer does not give (``pid`` on ``observer:=contact_force`` would run on theta_hat = 0 and
  saturate).

Every offline entry point applies both: ``simulate`` and campaign points derive
(:func:`derive`), and :func:`check_pair` runs wherever the cores are built
(``closed_loop.build_cores``: simulate, the batch, campaigns, lock step), so no path runs a
refused pair.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from pac_common.parameters import ParameterError


class CompositionError(ParameterError):
    """Two parts of a run that cannot work together (one line: both parts, and what would fit)."""

    def __init__(self, name: str, value: Any, message: str) -> None:
        self.name = name
        self.value = value
        self.allowed = message
        ValueError.__init__(self, message)


def derive(
    values: Mapping[str, Any], defaults: Mapping[str, Any] | None = None
) -> tuple[dict[str, Any], list[str]]:
    """``values`` (flat parameter names) with what the named parts imply where the user named
    nothing, and one line per derived value (for a log). ``defaults``: values the caller holds
    elsewhere (the rig launcher: the observer node's parameters), consulted like ``values``."""
    from pac_controller.laws import LAWS
    from pac_controller.parameters import ControllerParameters, ReferenceParameters

    given = {**(defaults or {}), **values}
    out = dict(values)
    notes: list[str] = []
    law = str(given.get("law", ControllerParameters().law))
    if "observer" not in given and law in LAWS and LAWS[law].observer is not None:
        out["observer"] = LAWS[law].observer
        notes.append(f"observer:={out['observer']} (what law {law} runs on)")
    if given.get("catenary_model") == "fe" and "span_length" not in given:
        from pac_plant.catenary.catenary_file import load_catenary
        from pac_plant.parameters import PlantOptions

        catenary = str(given.get("catenary", PlantOptions().catenary))
        out["span_length"] = load_catenary(catenary).data.span
        notes.append(f"span_length:={out['span_length']:g} (the mean span of the FE line {catenary})")
    actuator = str(given.get("actuator", "ideal"))
    if actuator != "ideal" and "actuator_static_force" not in given:
        # The actuator's range is about the static force the pantograph is pressed with: the
        # run's reference (a passive law commands it; its default is the reference's default).
        default = ReferenceParameters().force_amplitude
        out["actuator_static_force"] = float(given.get("force_amplitude", default))
        notes.append(
            f"actuator_static_force:={out['actuator_static_force']:g} (the run's force_amplitude: "
            f"the {actuator} actuator's range is about it)"
        )
    if actuator != "ideal" and "u_min" not in given and "u_max" not in given:
        notes.extend(_actuator_limits(actuator, {**given, **out}, out))
    return out, notes


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


def check_pair(law: str, observer: str) -> None:
    """Refuse (CompositionError) law ``law`` on observer ``observer`` if it needs what that one
    does not give; one line naming both and what would fit."""
    from pac_controller.laws import LAWS
    from pac_observer.parameters import OBSERVER_GIVES

    missing = LAWS[law].needs - OBSERVER_GIVES[observer]
    if not missing:
        return
    fitting_laws = [name for name, entry in LAWS.items() if entry.needs <= OBSERVER_GIVES[observer]]
    fitting_observers = [name for name, gives in OBSERVER_GIVES.items() if LAWS[law].needs <= gives]
    raise CompositionError(
        "law",
        law,
        f"law '{law}' needs {', '.join(sorted(missing))}, which observer '{observer}' does not give: "
        f"run it on observer:={' or '.join(fitting_observers)}, or on observer '{observer}' one of "
        f"law:={', '.join(fitting_laws)}",
    )
