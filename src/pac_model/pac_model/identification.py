"""A nominal 2-DOF identified from a pantograph file: the model the observer and controller are told
when the plant is not the paper's pantograph (docs/vehicle_and_hardware.md, "An identified nominal").

Procedure. The controller's model is the paper's 2-DOF (head m1 -k1, b1- frame m2 -b2- roof, the
actuator on the frame) working in contact: eq. (5) with the wire's spring k_c on the head. Its
frequency response from the actuator force u to the head and frame heights,

    H(omega) = (K + k_c e_h e_h^T - omega^2 M + i omega C)^-1 e_a,

is fitted to the same response of the plant's chain (any masses, springs and dampers, the roof
fixed) at log-spaced frequencies over a band, by nonlinear least squares (scipy's
``least_squares``) on the logarithms of m1, b1, k1, m2, b2 (positive by construction), each
residual the complex misfit divided by the channel's largest magnitude over the band: both channels
count equally, and the fit follows the response where it is large (its resonances, what the
controller acts on). Measured for ``three_mass`` (three modes in the band, a 2-DOF has two): a
misfit relative to the magnitude at each frequency, or of the logarithms, is ruled by the frame's
anti-resonances (near zeros no 2-DOF has) and lands on swapped masses with errors of 100-500 %. The frame of
the fit is the chain's actuator mass, the head its head. The contact spring is needed because a
2-DOF with no roof spring has no static stiffness: free, its response grows without bound at low
frequency where the chain's roof spring holds it; in contact both sit on k_c.

``python -m pac_model.identification`` writes the fitted pantograph file (its procedure and fit
error in its ``source``).
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.optimize import least_squares

from .pantograph_file import PantographFile, Table1Values, load_pantograph_file, table1_file
from .parameters import CatenaryParameters, PantographParameters

#: The fitted parameters, in the order of the fit's vector (the fields of PantographParameters).
NAMES = ("m1", "b1", "k1", "m2", "b2")
#: Default band [Hz] and contact stiffness [N/m]: the issue's 0-20 Hz (20 Hz is EN 50317's
#: low-pass, the band the contact force is judged in; 0.2 Hz instead of 0: judgement, a log grid
#: needs a positive start and the response is flat below the bounce mode), and the paper's mean
#: catenary stiffness k0 (Table 1): what the nominal model is told the wire is.
BAND = (0.2, 20.0)
CONTACT_STIFFNESS = CatenaryParameters().k0
POINTS = 200


def frequency_response(
    chain: PantographFile, frequencies: np.ndarray, contact_stiffness: float
) -> np.ndarray:
    """(len(frequencies), 2) complex: head and actuator-mass heights per unit actuator force, the head
    on a spring ``contact_stiffness`` to the ground, the roof fixed."""
    mass, stiffness, damping, roof = chain.matrices()
    n = chain.n
    k = stiffness + np.diag(roof)
    k[chain.head, chain.head] += contact_stiffness
    force = np.zeros(n)
    force[chain.actuator] = 1.0
    out = np.empty((len(frequencies), 2), dtype=complex)
    for i, f in enumerate(np.asarray(frequencies, dtype=float)):
        w = 2 * math.pi * f
        x = np.linalg.solve(k - w * w * np.diag(mass) + 1j * w * damping, force)
        out[i] = x[chain.head], x[chain.actuator]
    return out


def _two_dof(values: np.ndarray) -> PantographFile:
    """The paper's 2-DOF chain with m1, b1, k1, m2, b2 = ``values``."""
    m1, b1, k1, m2, b2 = (float(v) for v in values)
    return table1_file(PantographParameters(m1=m1, b1=b1, k1=k1, m2=m2, b2=b2))


@dataclass(frozen=True)
class Fit:
    """The fitted 2-DOF and its misfit over the band: the largest and the RMS of
    |H_fit - H| / max|H| per channel (head, frame; max over the band)."""

    values: Table1Values
    largest: tuple[float, float]
    rms: tuple[float, float]


def misfit(response: np.ndarray, fitted: np.ndarray) -> tuple[tuple[float, float], tuple[float, float]]:
    """(largest, RMS) of |fitted - response| / max|response| per channel over the frequencies."""
    e = np.abs(fitted - response) / np.abs(response).max(axis=0)
    return (float(e[:, 0].max()), float(e[:, 1].max())), tuple(
        float(v) for v in np.sqrt(np.mean(e**2, axis=0))
    )  # type: ignore[return-value]


def fit_two_dof(
    response: np.ndarray, frequencies: np.ndarray, contact_stiffness: float, start: PantographParameters
) -> Fit:
    """The 2-DOF whose response (:func:`frequency_response`) fits ``response`` best in the relative
    least-squares sense, from ``start``."""
    scale = np.abs(response).max(axis=0)

    def residual(log_values: np.ndarray) -> np.ndarray:
        h = frequency_response(_two_dof(np.exp(log_values)), frequencies, contact_stiffness)
        e = (h - response) / scale
        return np.concatenate([e.real.ravel(), e.imag.ravel()])

    x0 = np.log([getattr(start, name) for name in NAMES])
    result = least_squares(residual, x0, xtol=1e-15, ftol=1e-15, gtol=1e-15, max_nfev=20000)
    values = np.exp(result.x)
    largest, rms = misfit(response, frequency_response(_two_dof(values), frequencies, contact_stiffness))
    table: Table1Values = dict(zip(NAMES, (float(v) for v in values), strict=True))  # type: ignore[assignment]
    return Fit(table, largest, rms)


def band(low: float = BAND[0], high: float = BAND[1], points: int = POINTS) -> np.ndarray:
    """The fit's log-spaced frequencies [Hz]."""
    return np.geomspace(low, high, points)


def identify(chain: PantographFile, contact_stiffness: float = CONTACT_STIFFNESS) -> Fit:
    """The 2-DOF fitted to ``chain`` over :data:`BAND`, from the paper's Table 1 (a start inside the
    basin: same orders of magnitude)."""
    f = band()
    return fit_two_dof(
        frequency_response(chain, f, contact_stiffness), f, contact_stiffness, PantographParameters()
    )


def pantograph_yaml(chain: PantographFile, fit: Fit, contact_stiffness: float) -> str:
    """The fitted 2-DOF as a pantograph file (docs/catenary.md, "The pantograph file"), with the
    source chain's uplift (it acts on the actuator's mass in both) and the procedure in ``source``."""
    v = fit.values
    low, high = BAND
    return f"""# A 2-DOF identified from the pantograph '{chain.name}' by `python -m pac_model.identification`
# (docs/vehicle_and_hardware.md, "An identified nominal"): do not edit, re-run the command.
# Format: docs/catenary.md, "The pantograph file". Units SI (kg, N/m, N s/m, N).
name: {chain.name}_identified_2dof
source: >
  The paper's 2-DOF shape fitted to the frequency response of the pantograph '{chain.name}' from the
  actuator force to the head and actuator-mass heights, the head on a contact spring of
  {contact_stiffness:g} N/m (the paper's mean catenary stiffness k0), the roof fixed; {POINTS}
  log-spaced frequencies over {low:g}-{high:g} Hz; nonlinear least squares on log m1, b1, k1, m2, b2
  of the complex misfit over each channel's largest magnitude, from Table 1. Fit error
  |H_fit - H| / max|H|, largest over the band: head {fit.largest[0]:.4f}, frame
  {fit.largest[1]:.4f}; RMS: head {fit.rms[0]:.4f}, frame {fit.rms[1]:.4f}. Uplift: the source
  pantograph's (both act on the actuator's mass).
masses:
  - {{name: head, mass: {v["m1"]:.6g}}}
  - {{name: frame, mass: {v["m2"]:.6g}}}
springs:
  - {{between: [head, frame], stiffness: {v["k1"]:.6g}}}
dampers:
  - {{between: [head, frame], damping: {v["b1"]:.6g}}}
  - {{between: [frame, roof], damping: {v["b2"]:.6g}}}
head: head
actuator: frame
static_uplift: {chain.static_uplift:g}
aerodynamic_uplift: {{c0: {chain.aero_c0:g}, c2: {chain.aero_c2:g}}}
"""


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m pac_model.identification", description=__doc__.split("\n")[0]
    )
    parser.add_argument(
        "pantograph", nargs="?", default="three_mass", help="the plant's pantograph file or preset"
    )
    parser.add_argument("--out", type=Path, help="write the fitted pantograph file here (default: print it)")
    parser.add_argument("--contact-stiffness", type=float, default=CONTACT_STIFFNESS, help="k_c [N/m]")
    args = parser.parse_args(argv)
    chain = load_pantograph_file(args.pantograph)
    fit = identify(chain, args.contact_stiffness)
    text = pantograph_yaml(chain, fit, args.contact_stiffness)
    if args.out:
        args.out.write_text(text)
    else:
        sys.stdout.write(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
