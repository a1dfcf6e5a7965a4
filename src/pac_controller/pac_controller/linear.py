"""The linear design model of the fixed-gain laws (pid, lqr) and the loop they close.

At a constant stiffness k the model of eq. (11) is linear time-invariant:

    z' = A_k z + B u,     A_k = A + psi-row(k)  (A of eq. (12), the spring -k z1 / m1 of eq. (15)),
    F  = C_F z,           C_F = (k, 0, 0, 0)     (eq. (6)),         B = phi(1) (eq. (14)).

Sampled with a zero-order hold at the loop period and a command delay of d ticks
(u_k is applied over [t_{k+d}, t_{k+d+1}], docs/design.md), it is the discrete
system the pid and lqr designs are made for and checked against.
"""

from __future__ import annotations

import math

import numpy as np

from pac_model import model
from pac_model.parameters import PantographParameters


def contact_model(p: PantographParameters, k: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(A_k, B, C_F) of the pantograph pressed on a spring of constant stiffness k, eqs. (6), (11)-(15)."""
    a = model.state_matrix(p).copy()
    # psi(y) theta with theta = (k, 0, 0): only the z1 column of the head's row, -k / m1.
    a[2, 0] += model.output_regressor_row(1.0, 0.0, 0.0, p) @ np.array([k, 0.0, 0.0])
    b = model.input_vector(1.0, p)
    c = np.array([k, 0.0, 0.0, 0.0])
    return a, b, c


def discretise(a: np.ndarray, b: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Zero-order-hold sampling: (e^{A dt}, int_0^dt e^{A s} ds B)."""
    n = a.shape[0]
    import scipy.linalg  # here, not at import: a node starts without loading scipy

    m = scipy.linalg.expm(np.block([[a, b[:, None]], [np.zeros((1, n + 1))]]) * dt)
    return m[:n, :n], m[:n, n]


def with_delay(ad: np.ndarray, bd: np.ndarray, delay: int) -> tuple[np.ndarray, np.ndarray]:
    """The sampled plant with ``delay`` ticks of command delay.

    State (x_k, u_{k-d}, ..., u_{k-1}): the commands already sent and not yet applied.
    """
    n = ad.shape[0]
    if delay == 0:
        return ad, bd
    size = n + delay
    a = np.zeros((size, size))
    a[:n, :n] = ad
    a[:n, n] = bd  # the oldest pending command is the one applied now
    for j in range(delay - 1):
        a[n + j, n + j + 1] = 1.0
    b = np.zeros(size)
    b[-1] = 1.0
    return a, b


def frequency_response(
    p: PantographParameters, k: float, w: float | np.ndarray, delay_seconds: float
) -> np.ndarray:
    """G(j w) e^{-j w tau} at each w: from u to F of the contact model, with a pure delay tau."""
    a, b, c = contact_model(p, k)
    w = np.atleast_1d(np.asarray(w, dtype=float))
    resolvent = 1j * w[:, None, None] * np.eye(a.shape[0]) - a  # one (j w I - A) per frequency
    g = np.linalg.solve(resolvent, np.broadcast_to(b, (w.size, b.size))[..., None])[..., 0] @ c
    return g * np.exp(-1j * w * delay_seconds)


def spectral_radius(a: np.ndarray) -> float:
    """max |eig(a)|: a sampled loop is stable iff this is below 1."""
    return float(np.max(np.abs(np.linalg.eigvals(a))))


def loop_with_output_feedback(
    p: PantographParameters,
    k: float,
    dt: float,
    delay: int,
    controller: tuple[np.ndarray, np.ndarray, np.ndarray, float],
) -> np.ndarray:
    """Closed-loop matrix of the sampled plant (k, delay) with a discrete controller on e = -F.

    ``controller`` = (Ac, Bc, Cc, Dc): c_{k+1} = Ac c_k + Bc e_k, u_k = Cc c_k + Dc e_k.
    """
    a, b, c_f = contact_model(p, k)
    ad, bd = discretise(a, b, dt)
    ap, bp = with_delay(ad, bd, delay)
    cp = np.zeros(ap.shape[0])
    cp[:4] = c_f
    ac, bc, cc, dc = controller
    n, m = ap.shape[0], ac.shape[0]
    out = np.zeros((n + m, n + m))
    # u_k = Cc c_k - Dc Cp x_k enters the plant through bp.
    out[:n, :n] = ap - dc * np.outer(bp, cp)
    out[:n, n:] = np.outer(bp, cc)
    out[n:, :n] = -np.outer(bc, cp)
    out[n:, n:] = ac
    return out


def wrap_angle(x: float) -> float:
    """x in (-pi, pi]."""
    return x - 2.0 * math.pi * math.ceil((x - math.pi) / (2.0 * math.pi))
