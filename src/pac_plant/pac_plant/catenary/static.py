"""Static equilibrium with droppers that carry tension only (a dropper may hang slack at rest).

The line's linear static solve (``Line.solve_static``) treats every dropper as a spring that
pulls and pushes. A real dropper is a wire: it carries tension only, so where the contact wire
would have to be pushed up to meet its design height (a dropper cut too long), the dropper hangs
slack and the wire sits where its neighbours and its tension leave it.

With the taut solution w_t (every dropper a spring) and its elongations e_t, removing the
droppers of a set S is a rank-|S| change of the stiffness: with g_j = e_(w_m,j) - e_(w_c,j) and
the dropper force f_j = k_j e_j removed,

    w = w_t + K^-1 G_S c,   e_S(w) = e_S(w_t) + D_SS c,   c = k_S e_S(w)   (D = G^T K^-1 G),

so c solves (diag(1/k_S) - D_SS) c = e_S(w_t): one small dense solve per active set, no new
factorisation. The set is iterated (a primal active-set / semi-smooth Newton iteration: slack
exactly where the elongation it produces is negative) until it agrees with its own solution.
The tension-only problem is the minimum of a strictly convex energy, so its solution is unique;
the iteration's answer is checked, not trusted (``TensionOnlyEquilibrium.consistent``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

#: Active-set passes before giving up (each pass: one small dense solve).
MAX_PASSES = 100


@dataclass(frozen=True)
class TensionOnlyEquilibrium:
    """The static state of a line whose droppers carry tension only."""

    w: np.ndarray  # every DOF [m]
    elongation: np.ndarray  # per dropper [m]; negative: slack
    slack: np.ndarray  # indices of the slack droppers, ascending
    passes: int

    def consistent(self) -> bool:
        """The set is the one its solution gives: slack droppers shortened, the others not."""
        slack = np.zeros(len(self.elongation), dtype=bool)
        slack[self.slack] = True
        return bool(np.all(self.elongation[slack] <= 0.0) and np.all(self.elongation[~slack] >= 0.0))


def tension_only_equilibrium(
    solve: Callable[[np.ndarray], np.ndarray],
    w_taut: np.ndarray,
    elongation_taut: np.ndarray,
    wc: np.ndarray,
    wm: np.ndarray,
    stiffness: np.ndarray,
) -> TensionOnlyEquilibrium:
    """Equilibrium from the taut one (``w_taut``, ``elongation_taut``; ``solve``: f -> K^-1 f with
    every dropper taut; dropper j joins DOFs ``wc[j]`` and ``wm[j]`` with ``stiffness[j]``)."""
    slack = np.flatnonzero(elongation_taut < 0.0)
    if len(slack) == 0:
        return TensionOnlyEquilibrium(w_taut, elongation_taut, slack, 0)
    n = len(w_taut)
    # K^-1 g_j only for the droppers a pass takes slack (a whole line's ~500 columns would be most
    # of its set-up): solved once each, as a banded solve treats every column on its own.
    solved: dict[int, np.ndarray] = {}

    def columns(js: np.ndarray) -> np.ndarray:
        """(n, len(js)): column k is K^-1 g_(js[k]); column-major, as a column selection of the
        whole (n, nd) solution would be (the products below then sum in the same order)."""
        missing = np.array([j for j in js if j not in solved], dtype=np.int64)
        if len(missing):
            g = np.zeros((n, len(missing)))
            g[wm[missing], np.arange(len(missing))] = 1.0
            g[wc[missing], np.arange(len(missing))] -= 1.0
            y_missing = solve(g)
            for k, j in enumerate(missing):
                solved[int(j)] = y_missing[:, k]
        return np.asfortranarray(np.stack([solved[int(j)] for j in js], axis=1))

    passes = 0
    c = np.zeros(0)
    while passes < MAX_PASSES:
        passes += 1
        y = columns(slack)
        d = np.asfortranarray(y[wm, :] - y[wc, :])  # the slack columns of D = G^T K^-1 G
        c = np.linalg.solve(np.diag(1.0 / stiffness[slack]) - d[slack, :], elongation_taut[slack])
        elongation = elongation_taut + d @ c
        new = np.flatnonzero(elongation < 0.0)
        if np.array_equal(new, slack):
            break
        slack = new
    else:
        raise RuntimeError(f"tension-only static state: the active set did not settle in {MAX_PASSES} passes")
    y = columns(slack)
    w = w_taut + y @ c
    elongation = elongation_taut + np.asfortranarray(y[wm, :] - y[wc, :]) @ c
    return TensionOnlyEquilibrium(w, elongation, slack, passes)
