"""Turbulent aerodynamic uplift: a seeded fluctuation of the pantograph's aerodynamic force.

Model (docs/vehicle_and_hardware.md, "Turbulent uplift"): the aerodynamic uplift c0 + c2 v^2 of the
pantograph file fluctuates about its mean by a stationary random force with a flat one-sided PSD
over a band (0.5-20 Hz) and an RMS that is a fraction of that mean (5-10 %: judgement,
docs/catenary_data.md section 9; no measured spectrum was found). It is drawn, as the track under
the car body (``car_body``), as a sum of cosines (the spectral representation): one per log-spaced
bin of the band, its frequency drawn inside the bin (the sum never repeats), amplitude
sqrt(2 S df) with S = sigma^2 / (f_high - f_low), phase uniform, seeded. It acts on the actuator's
mass with the mean uplift; the plant holds it over a tick as its mean (``car_body.roof_force`` of
the cosines with k = 1, c = 0: the same closed form).
"""

from __future__ import annotations

import math

import numpy as np

from .car_body import TERMS, RoofMotion

#: The band of the fluctuation [Hz] (judgement, docs/catenary_data.md section 9).
BAND = (0.5, 20.0)


def gusts(rms: float, seed: int, band: tuple[float, float] = BAND) -> RoofMotion:
    """The fluctuating force [N] of RMS ``rms`` over ``band`` (cosines of amplitude [N], angular
    frequency [rad/s] and phase: a RoofMotion, whose ``at`` gives the force as its height)."""
    low, high = band
    rng = np.random.default_rng([seed, 0x6A5])
    edges = np.geomspace(low, high, TERMS + 1)
    frequency = edges[:-1] + rng.random(TERMS) * np.diff(edges)
    amplitude = np.sqrt(2.0 * rms**2 / (high - low) * np.diff(edges))
    return RoofMotion(amplitude, 2 * math.pi * frequency, rng.uniform(0.0, 2 * math.pi, TERMS))
