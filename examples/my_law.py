"""My own control law for the pac rig: a PI on the estimated contact force.

Run it wherever a law is named (the path as you would type it from this folder's parent):

    ros2 run pac_rig simulate bags/my_law -p law:=examples/my_law.py
    ros2 run pac_controller controller_node --ros-args -p law:=examples/my_law.py
    a campaign SPEC:   grid: {law: [examples/my_law.py, passive]}

The protocol (docs/laws.md, "Your own law"): NEEDS, optionally design and STATE_SIZE, then
output and optionally restart and commit.  The rig's safety chain limits what ``output`` asks
for (slew limit, saturation to [u_min, u_max]); an estimate with a non-finite value of what NEEDS
names, or a non-finite demand, is answered by the fallback force instead.

The law, with e = F_r - F_hat (F_hat: the observer's contact-force estimate):

    u_k     = F_r,k + KP e_k + I_k                   (F_r: the static balance u = F, eq. (3))
    I_{k+1} = I_k + dt KI e_k   if u_k was commanded as asked, else I_k   (conditional integration)

so the integral stops growing while the actuator is at a limit (anti-windup).  After any command
that was not the law's own (the start, a fallback) it restarts bumplessly: I is set so that its
first demand equals the force the actuator holds.
"""

import numpy as np
from numba import njit

#: False: the law runs at Python speed. True: numba compiles output, restart and commit, and the
#: rig compiles them into its safety chain and its offline loop (docs/laws.md, "Your own law").
COMPILED = False
compiled = njit if COMPILED else (lambda function: function)

#: What the law reads of the estimate: F_hat only (it runs on either observer).
NEEDS = ("contact_force_hat",)

#: Proportional gain [N per N of force error] and integral gain [1/s]. Picked by hand from a few
#: 4 s runs of the default scenario (not designed: pac's pid is): KI = 5 or KP = 0.8 made it
#: oscillate into the actuator's limits; these gave sigma(F) 44 N against passive's 56 N.
KP = 0.5
KI = 2.0

#: The law's memory (``state``), by index.
INTEGRAL, BUMPLESS, BUMPLESS_FROM, PENDING_INTEGRAL, PENDING_ERROR, PENDING_U = range(6)
STATE_SIZE = 6


def design(setup):
    """The law's constants, once per run: its gains and the sample period [s]."""
    return np.array([KP, KI, setup.sample_period])


@compiled
def restart(consts, state, has_u, u_applied):
    """Forget the integral; the next demand continues from ``u_applied`` when there is one."""
    state[INTEGRAL] = 0.0
    state[BUMPLESS] = 1.0 if has_u else 0.0
    state[BUMPLESS_FROM] = u_applied


@compiled
def output(consts, state, t, f_r, z_hat, theta_hat, f_hat):
    """The demand at time ``t`` (f_r[0] is F_r); what commit needs is noted in ``state``."""
    kp = consts[0]
    error = f_r[0] - f_hat
    integral = state[INTEGRAL]
    if state[BUMPLESS] != 0.0:
        integral = state[BUMPLESS_FROM] - f_r[0] - kp * error  # u equals the actuator's force
    u = f_r[0] + kp * error + integral
    state[PENDING_INTEGRAL], state[PENDING_ERROR], state[PENDING_U] = integral, error, u
    return u


@compiled
def commit(consts, state, u_applied):
    """The force the safety chain let through: integrate only when it is the demand itself."""
    ki, dt = consts[1], consts[2]
    integral = state[PENDING_INTEGRAL]
    if u_applied == state[PENDING_U]:
        integral += dt * ki * state[PENDING_ERROR]
    state[INTEGRAL] = integral
    state[BUMPLESS] = 0.0
