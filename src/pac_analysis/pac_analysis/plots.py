"""Figures in the style of the paper's Figs. 3-5, from any pac bag (matplotlib, PNG)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from pac_bag.reader import BagData

from .metrics import stamp_seconds


def run_figure(bag: BagData, title: str, path: Path) -> Path:
    """Three panels: F with F_r and F_hat (Fig. 3), u (Fig. 4), k with k_hat (Fig. 5)."""
    truth, command, estimate = (bag.topics.get(n) for n in ("plant_truth", "command", "estimate"))
    fig, axes = plt.subplots(3, 1, figsize=(9, 8.5), sharex=True, constrained_layout=True)
    ax_f, ax_u, ax_k = axes
    if command is not None and len(command):
        ax_f.plot(stamp_seconds(command), command["force_reference"], "k-", lw=1.6, label="reference $F_r$")
    if truth is not None and len(truth):
        ax_f.plot(
            stamp_seconds(truth), truth["contact_force"], "C3--", lw=1.1, label="true contact force $F$"
        )
    if estimate is not None and len(estimate):
        ax_f.plot(
            stamp_seconds(estimate),
            estimate["contact_force_hat"],
            "C0:",
            lw=1.0,
            label=r"estimate $\hat F = \hat k z_1$",
        )
    ax_f.set_ylabel("force [N]")
    ax_f.set_title(f"{title}: contact force (cf. Fig. 3)")
    ax_f.legend(loc="best", fontsize=8)
    if command is not None and len(command):
        ax_u.plot(stamp_seconds(command), command["u"], "C2-", lw=0.9, label="actuator force $u$")
        ax_u.legend(loc="best", fontsize=8)
    ax_u.set_ylabel("u [N]")
    ax_u.set_title("control action (cf. Fig. 4)")
    if truth is not None and len(truth):
        ax_k.plot(stamp_seconds(truth), truth["stiffness"] / 1e3, "k-", lw=1.4, label="true $k(t)$")
    if estimate is not None and len(estimate):
        ax_k.plot(
            stamp_seconds(estimate),
            estimate["stiffness_hat"] / 1e3,
            "C1--",
            lw=1.1,
            label=r"estimate $\hat k(t)$",
        )
    ax_k.set_ylabel("stiffness [kN/m]")
    ax_k.set_xlabel("simulated time t [s]")
    ax_k.set_title("catenary stiffness and its estimate (cf. Fig. 5)")
    ax_k.legend(loc="best", fontsize=8)
    for ax in axes:
        ax.grid(True, alpha=0.3)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def overlay_figure(
    bags: dict[str, BagData], title: str, path: Path, window: tuple[float, float] | None = None
) -> Path:
    """True contact force of several runs on one axis (e.g. passive vs active)."""
    fig, ax = plt.subplots(figsize=(9, 4), constrained_layout=True)
    ref_drawn = False
    for i, (name, bag) in enumerate(bags.items()):
        truth = bag.topics["plant_truth"]
        t = stamp_seconds(truth)
        keep = np.ones_like(t, dtype=bool) if window is None else (t >= window[0]) & (t <= window[1])
        ax.plot(t[keep], truth["contact_force"][keep], f"C{i}-", lw=1.0, label=f"{name}: $F$")
        command = bag.topics.get("command")
        if not ref_drawn and command is not None and len(command):
            tc = stamp_seconds(command)
            kc = np.ones_like(tc, dtype=bool) if window is None else (tc >= window[0]) & (tc <= window[1])
            ax.plot(tc[kc], command["force_reference"][kc], "k--", lw=1.0, label="reference $F_r$")
            ref_drawn = True
    ax.axhline(0.0, color="r", lw=0.8, alpha=0.6)
    ax.set_xlabel("simulated time t [s]")
    ax.set_ylabel("contact force [N]")
    ax.set_title(title)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path
