"""An open-loop feedforward as a user law file: u_k = F_r,k + p_k, the pattern p from a file.

The instrument of ``realistic_pair_bound`` (pair_bound.py), which runs it as ``law:=<this file>``
through the rig's user-law protocol (pac_controller.user_law) so that the command passes the same
safety chain, delay and actuator as any law's. p is a 1-D ``.npy`` array, one value per tick from
the run's start [N], named by the environment variable ``PAC_FEEDFORWARD_TABLE``; past its end the
last value holds. It reads nothing of the estimate: the leader presses the same force whatever the
line does, so that the forces of two runs differ by what p did alone.
"""

from __future__ import annotations

import os
from typing import TYPE_CHECKING

import numpy as np
from numba import njit

from pac_common.parameters import ParameterError

if TYPE_CHECKING:
    from pac_controller.user_law import LawSetup

NEEDS = ()
#: The environment variable that names the pattern's file.
TABLE_VARIABLE = "PAC_FEEDFORWARD_TABLE"


def design(setup: LawSetup) -> np.ndarray:
    """The constants: the sample period, then the pattern p (one value per tick)."""
    path = os.environ.get(TABLE_VARIABLE, "")
    if not path:
        raise ParameterError(
            "law", "feedforward_law.py", f"the environment variable {TABLE_VARIABLE} set to a .npy file"
        )
    try:
        table = np.asarray(np.load(path), dtype=float)
    except (OSError, ValueError) as error:
        raise ParameterError("law", path, f"a readable .npy file ({error})") from error
    if table.ndim != 1 or table.size == 0 or not np.all(np.isfinite(table)):
        raise ParameterError("law", path, "a 1-D array of finite forces [N], one per tick")
    return np.concatenate(([setup.sample_period], table))


@njit(cache=False)  # a law loaded from its file: numba caches no closure of it (pac_controller.user_law)
def output(
    consts: np.ndarray,
    state: np.ndarray,
    t: float,
    f_r: np.ndarray,
    z_hat: np.ndarray,
    theta_hat: np.ndarray,
    f_hat: float,
) -> float:
    """u = F_r + p at the tick nearest t (the last value past the pattern's end)."""
    size = consts.shape[0] - 1
    tick = min(max(int(t / consts[0] + 0.5), 0), size - 1)
    return f_r[0] + consts[1 + tick]
