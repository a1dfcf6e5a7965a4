"""What pac's compiled laws share: the mode of a command, the integrator's restart, the F_hat fed back.

A compiled law of pac's (an entry of ``laws.LAWS`` with ``kernel``) is a module with four numba
functions named after the law, on the controller's records (``kernels.CONTROLLER_PARAMS`` ``p``
and ``kernels.CONTROLLER_STATE`` ``s``) and the law's arrays ``table`` and ``memory``:

- ``<law>_restart(p, s, table, memory, has_u, u_applied)``: forget the law's state; its next
  output continues from ``u_applied`` (``has_u`` False: at rest);
- ``<law>_output(p, s, table, memory, tick, t, f_r, z_hat, theta_hat, f_hat, force_measured)``:
  the unlimited force u_law and three law-specific errors, remembered for commit;
- ``<law>_mode(p, s)``: the mode code of its command (:data:`ACTIVE` or :data:`PASSIVE`);
- ``<law>_commit(p, s, table, memory, tick, u_applied)``: the limited force actually commanded.

The controller's step calls them through ``law_dispatch``, which is generated from the registry
(``law_dispatch_source``), never written by hand.
"""

from __future__ import annotations

from numba import njit

from pac_common import messages
from pac_model import model

#: Command.mode by code (``MODES[code]``): what the controller's step returns as its mode.
MODES = tuple(messages.MODES)  # the message's codes
ACTIVE, PASSIVE, FALLBACK = (MODES.index(mode) for mode in ("active", "passive", "fallback"))


@njit(cache=True, error_model="numpy")
def contact_force_estimate(t: float, omega: float, z_hat, theta_hat) -> float:
    """F_hat = k_hat z_hat_1, k_hat = v(t)^T theta_hat (eqs. (6), (8)): controller.contact_force_estimate."""
    return model.contact_force(model.stiffness(t, omega, theta_hat), z_hat[0], False)


@njit(cache=True, error_model="numpy")
def fed_back_force(p, t: float, z_hat, theta_hat, f_hat: float) -> float:
    """The F_hat pid and lqr feed back (``force_estimate``): the estimate's own contact_force_hat
    when the law reads it (``uses_contact_force``), else k_hat z_hat_1 (eqs. (6), (8))."""
    if p.uses_contact_force:
        return f_hat
    return contact_force_estimate(t, p.omega, z_hat, theta_hat)


@njit(cache=True, error_model="numpy")
def restart_memory(s, has_u: bool, u_applied: float) -> None:
    """The integrator laws' memory forgotten: the next output starts bumplessly from ``u_applied``
    (``has_u`` False: at rest). Laws without memory clear it too, so a record never carries one
    law's memory into another's run."""
    s.has_bumpless, s.bumpless_from = has_u, u_applied
    s.started = False
    s.integral, s.rate, s.derivative, s.last_error, s.law_last_tick = 0.0, 0.0, 0.0, 0.0, 0
