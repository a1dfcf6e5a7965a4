"""The compiled observers' dispatch: generated from ``pac_observer.observers.OBSERVERS`` by
``python -m pac_observer.observer_dispatch_source --write``. Do not edit.

One branch per compiled observer on the record's code (``OBSERVER_CONSTS.kind``), calling its
module's ``<name>_update`` (observers.py). An unknown code is a divergence of its own.
"""

from __future__ import annotations

from numba import njit

from pac_common.divergence import UNKNOWN_OBSERVER
from pac_observer import contact_force, head_balance, observer

#: Observer name -> the code the compiled functions dispatch on (the registry's order).
OBSERVER_CODES = {
    "adaptive": 0,
    "contact_force": 1,
    "head_balance": 2,
}


@njit(cache=True, error_model="numpy")
def observer_update(k, t, oc, os, bank, y1, y2, u_applied, head_acceleration):
    """The observer of the records at tick k: (status, stiffness_hat, contact_force_hat)."""
    kind = oc.kind
    if kind == 0:
        return observer.adaptive_update(k, t, oc, os, bank, y1, y2, u_applied, head_acceleration)
    elif kind == 1:
        return contact_force.contact_force_update(k, t, oc, os, bank, y1, y2, u_applied, head_acceleration)
    elif kind == 2:
        return head_balance.head_balance_update(k, t, oc, os, bank, y1, y2, u_applied, head_acceleration)
    return UNKNOWN_OBSERVER, 0.0, 0.0
