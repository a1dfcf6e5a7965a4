"""My own observer for the pac rig: the contact force's slow part from the momentum balance.

Run it wherever an observer is named (the path as you would type it from this folder's parent):

    ros2 run pac_rig simulate bags/my_observer -p observer:=examples/my_observer.py -p law:=pid
    ros2 run pac_observer observer_node --ros-args -p observer:=examples/my_observer.py
    a campaign SPEC:   grid: {observer: [examples/my_observer.py, contact_force]}

The protocol (docs/laws.md, "Your own observer"): GIVES, optionally READS, and a class Observer
with update, reset and tick. A law that needs what GIVES does not name (theta_hat here) is
refused before the run; a pid or lqr law feeds back this F_hat.

The estimate, with F_a the actuator's force and dt the time since the last sample:

    F_hat_k = F_hat_{k-1} + (1 - exp(-dt / TAU)) (F_a,k - F_hat_{k-1}),    F_hat_0 = F_a,0

Over seconds the pantograph's momentum balance makes its mean contact force the mean force on
it, the actuator's (up to the roof spring's small share), so this F_hat is the contact force's
slow part and nothing faster: a yardstick, not an estimate of the span's force pattern. z_hat is
the measured positions and their differences over the last sample.
"""

import math

import numpy as np

from pac_observer.observer import Estimate

#: What it gives a law besides z_hat: F_hat, no theta_hat.
GIVES = ("contact_force_hat",)
#: The low-pass's time constant [s].
TAU = 0.5


class Observer:
    def __init__(self, pantograph, track, params, sample_period):
        self.sample_period = sample_period
        self.reset()

    def reset(self):
        self.tick = -1
        self.force = math.nan
        self.y = (math.nan, math.nan)

    def update(self, tick, y, actuator_force, head_acceleration=math.nan):
        y1, y2 = float(y[0]), float(y[1])
        if self.tick < 0:
            self.force, v1, v2 = float(actuator_force), 0.0, 0.0
        else:
            gap = (tick - self.tick) * self.sample_period
            self.force += (1.0 - math.exp(-gap / TAU)) * (float(actuator_force) - self.force)
            v1, v2 = (y1 - self.y[0]) / gap, (y2 - self.y[1]) / gap
        self.tick, self.y = tick, (y1, y2)
        return Estimate(
            tick=tick,
            time=tick * self.sample_period,
            z_hat=np.array([y1, y2, v1, v2]),
            theta_hat=np.zeros(3),
            stiffness_hat=0.0,
            contact_force_hat=self.force,
            innovation=np.zeros(2),
        )
