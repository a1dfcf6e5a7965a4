"""Which parts of a run fit together: what a run derives from the parts it is given, and what it
refuses before it starts.

A law states what it needs of the estimate besides z_hat (``pac_controller.laws.LAWS``:
``needs``) and the observer it runs on when none is named (``observer``); an observer states what
it gives (``pac_observer.parameters.OBSERVER_GIVES``). From them:

- **derived**, where the user named nothing: ``law:=line_adaptive`` alone runs on the observer it
  needs (``observer:=contact_force``); on the FE line (``catenary_model:=fe``) the observer and
  the controller are told the span of the line the plant runs (its catenary file's mean span),
  not the 65 m default of the lumped model;
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
    from pac_controller.parameters import ControllerParameters

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
    return out, notes


def check_pair(law: str, observer: str) -> None:
    """Refuse (CompositionError) law ``law`` on observer ``observer`` if it needs what that one
    does not give; one line naming both and what would fit."""
    from pac_controller.laws import LAWS, law_entry
    from pac_observer.parameters import OBSERVER_GIVES

    needs = law_entry(law).needs  # a user's law file: loaded here, refused in one line if it cannot be
    missing = needs - OBSERVER_GIVES[observer]
    if not missing:
        return
    fitting_laws = [name for name, entry in LAWS.items() if entry.needs <= OBSERVER_GIVES[observer]]
    fitting_observers = [name for name, gives in OBSERVER_GIVES.items() if needs <= gives]
    raise CompositionError(
        "law",
        law,
        f"law '{law}' needs {', '.join(sorted(missing))}, which observer '{observer}' does not give: "
        f"run it on observer:={' or '.join(fitting_observers)}, or on observer '{observer}' one of "
        f"law:={', '.join(fitting_laws)}",
    )
