"""The response-matrix tool (pac_experiments.catenary.line_response) against the analytic answer of a
time-invariant line: the paper's 2-DOF pantograph on a spring of constant stiffness."""

from __future__ import annotations

import numpy as np
import pytest

from pac_experiments.catenary.line_response import LineResponse, coupling, diagonal, regularised
from pac_rig.closed_loop import build_cores

pytestmark = pytest.mark.offline


def spring_response(p, k: complex, omega: np.ndarray) -> np.ndarray:
    """F / U of eqs. (3)-(4) with k(t) = k: head m1 on the spring k and on (k1, b1) to the frame m2,
    the frame damped by b2 to the car body, u on the frame; F = k z1 (an independent solve). A
    complex k is a line's impedance at one frequency (k + i c w: a spring with a damper)."""
    out = []
    for w in omega:
        s = 1j * w
        a = np.array(
            [
                [p.m1 * s**2 + p.b1 * s + p.k1 + k, -(p.b1 * s + p.k1)],
                [-(p.b1 * s + p.k1), p.m2 * s**2 + (p.b1 + p.b2) * s + p.k1],
            ]
        )
        z1, _ = np.linalg.solve(a, np.array([0.0, 1.0]))
        out.append(k * z1)
    return np.array(out)


def lumped(alpha: float) -> dict:
    """The lumped line of eq. (2) at 300 km/h, stiffness variation ``alpha`` (0: a constant spring)."""
    return {"catenary_model": "lumped", "alpha": alpha, "observer": "contact_force",
            "speed_kmh": 300.0, "span_length": 55.0}  # fmt: skip


def test_time_invariant_line_is_diagonal_with_the_spring_response() -> None:
    line = LineResponse(lumped(0.0))
    plant, _, _ = build_cores(line.scenario)
    k = plant.truth().stiffness
    base = line.run(np.zeros(line.count, complex))
    m = line.matrix(base, 20.0)
    # No coupling between harmonics on a time-invariant line (numerical floor only).
    assert coupling(m) < 1e-3
    omega = 2.0 * np.pi * line.frequencies
    # The zero-order hold of the sampled command: gain sinc(w dt / 2) (the law advances its half-tick lag).
    hold = np.sinc(omega * line.dt / (2.0 * np.pi))
    expected = spring_response(line.scenario.pantograph, k, omega) * hold
    np.testing.assert_allclose(diagonal(m), expected, rtol=5e-3)
    # With a known response, the regularised feedforward cancels a harmonic error: one that
    # U = 0 leaves (mu -> 0 on an invertible diagonal M is its exact inverse).
    e0 = np.zeros(line.count, complex)
    e0[0] = 10.0
    u = regularised(m, e0, 0.0)
    np.testing.assert_allclose(u[0], -10.0 / diagonal(m)[0], rtol=1e-4)  # M diagonal to its ~1e-6 floor


def test_a_time_varying_stiffness_couples_the_harmonics() -> None:
    """k(t) = k0 (1 + alpha cos(w t + beta)) (eq. 2) moves the force at h +- 1 for a command at h."""
    line = LineResponse(lumped(0.5))
    m = line.matrix(line.run(np.zeros(line.count, complex)), 20.0)
    assert coupling(m) > 0.2
