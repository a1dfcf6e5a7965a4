"""``DIR/report.md`` of a campaign and its PNG figures (matplotlib), from the rows of results.csv.

Figures: the contact-force quality against speed per value of the other axes (when
``speed_kmh`` is varied), and robustness maps (sigma over the first two varied
parameters of each grid, worst case over the grid's other axes). The EN 50367
criteria (sigma <= 0.3 Fm, Fm - 3 sigma > 0) are marked on both.
"""

from __future__ import annotations

import itertools
import math
import re
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.colors import LogNorm

from pac_common import markdown
from pac_common.contact_statistics import SIGMA_LIMIT_RATIO, en50367_criteria
from pac_experiments.campaign.run import STATUS_OK
from pac_experiments.campaign.spec import Spec, grid_keys
from pac_experiments.campaign.spec import same_value as _same

SPEED = "speed_kmh"
#: (mean, sigma, Fm - 3 sigma, contact loss) columns of the rows, by the SPEC's ``statistics``.
FORCE_COLUMNS = {
    "raw": ("contact_force_mean", "contact_force_std", "statistical_min", "contact_loss_percent"),
    "en50318": (
        "en50318_contact_force_mean",
        "en50318_contact_force_std",
        "en50318_statistical_min",
        "en50318_contact_loss_percent",
    ),
}


def _label(value: Any) -> str:
    if isinstance(value, list | tuple):
        return "(" + ", ".join(f"{v:g}" for v in value) + ")"
    if isinstance(value, float):
        return f"{value:g}"
    return str(value)


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9]+", "_", text).strip("_")


def _ok(row: dict) -> bool:
    return row.get("status") == STATUS_OK


def _value(row: dict, key: str) -> float:
    v = row.get(key)
    return float(v) if isinstance(v, int | float) and not isinstance(v, bool) else math.nan


def speed_figure(
    grid: dict[str, list], rows: list[dict], title: str, path: Path, statistics: str = "raw"
) -> Path | None:
    """sigma, sigma/Fm, Fm - 3 sigma, contact loss against speed; a line per combination of the other axes."""
    others = [a for a in grid if a != SPEED and len(grid[a]) > 1]
    fig, axes = plt.subplots(2, 2, figsize=(11, 7.5), sharex=True, constrained_layout=True)
    (ax_s, ax_r), (ax_m, ax_l) = axes
    plotted = False
    for i, combo in enumerate(itertools.product(*(grid[a] for a in others))):
        mine = [r for r in rows if all(_same(r.get(a), v) for a, v in zip(others, combo, strict=True))]
        mine = sorted((r for r in mine if _ok(r)), key=lambda r: _value(r, SPEED))
        if not mine:
            continue
        plotted = True
        label = ", ".join(f"{a}={_label(v)}" for a, v in zip(others, combo, strict=True)) or "runs"
        v = np.array([_value(r, SPEED) for r in mine])
        mean_key, sigma_key, _, loss_key = FORCE_COLUMNS[statistics]
        fm = np.array([_value(r, mean_key) for r in mine])
        sd = np.array([_value(r, sigma_key) for r in mine])
        loss = np.array([_value(r, loss_key) for r in mine])
        bad = np.array([not en50367_criteria(a, b).passed for a, b in zip(fm, sd, strict=True)], dtype=bool)
        color = f"C{i % 10}"
        ax_s.plot(v, sd, "o-", color=color, label=label, ms=4)
        ax_s.plot(v[bad], sd[bad], "x", color="red", ms=8, mew=2)
        ax_r.plot(v, sd / fm, "o-", color=color, ms=4)
        ax_m.plot(v, fm - 3 * sd, "o-", color=color, ms=4)
        ax_l.plot(v, loss, "o-", color=color, ms=4)
    if not plotted:
        plt.close(fig)
        return None
    ax_s.set_yscale("log")
    ax_s.set_ylabel(r"$\sigma$ [N]")
    ax_s.set_title(r"contact-force standard deviation $\sigma$ (red x: fails EN 50367)")
    ax_s.legend(fontsize=7, loc="best")
    ax_r.axhline(SIGMA_LIMIT_RATIO, color="red", ls="--", lw=1, label=r"EN 50367: $\sigma \leq 0.3 F_m$")
    ax_r.set_yscale("log")
    ax_r.set_ylabel(r"$\sigma / F_m$")
    ax_r.legend(fontsize=7, loc="best")
    ax_m.axhline(0.0, color="red", ls="--", lw=1, label=r"EN 50367: $F_m - 3\sigma > 0$")
    ax_m.set_ylabel(r"$F_m - 3\sigma$ [N]")
    ax_m.legend(fontsize=7, loc="best")
    ax_l.set_ylabel("contact lost (F <= 0) [%]")
    for ax in (ax_m, ax_l):
        ax.set_xlabel("speed [km/h]")
    for ax in axes.flat:
        ax.grid(True, alpha=0.3)
    fig.suptitle(title)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def robustness_map(
    grid: dict[str, list], rows: list[dict], x: str, y: str, title: str, path: Path, statistics: str = "raw"
) -> Path:
    """Heatmap of sigma over (x, y), worst case over the grid's other axes; EN 50367 failures hatched."""
    xs, ys = grid[x], grid[y]
    sigma = np.full((len(ys), len(xs)), np.nan)
    fails = np.zeros_like(sigma, dtype=bool)
    diverged = np.zeros_like(sigma, dtype=bool)
    for j, yv in enumerate(ys):
        for i, xv in enumerate(xs):
            cell = [r for r in rows if _same(r.get(x), xv) and _same(r.get(y), yv)]
            if any(not _ok(r) for r in cell):
                diverged[j, i] = True
                continue
            if cell:
                mean_key, sigma_key, _, _ = FORCE_COLUMNS[statistics]
                sd = np.array([_value(r, sigma_key) for r in cell])
                fm = np.array([_value(r, mean_key) for r in cell])
                sigma[j, i] = float(np.max(sd))
                fails[j, i] = not all(en50367_criteria(a, b).passed for a, b in zip(fm, sd, strict=True))
    fig, ax = plt.subplots(figsize=(1.3 * len(xs) + 3, 0.8 * len(ys) + 2.2), constrained_layout=True)
    finite = sigma[np.isfinite(sigma) & (sigma > 0)]
    norm = LogNorm(vmin=finite.min(), vmax=max(finite.max(), finite.min() * 1.01)) if finite.size else None
    image = ax.imshow(
        np.where(sigma > 0, sigma, np.nan), origin="lower", cmap="viridis", norm=norm, aspect="auto"
    )
    for j in range(len(ys)):
        for i in range(len(xs)):
            if diverged[j, i]:
                ax.add_patch(plt.Rectangle((i - 0.5, j - 0.5), 1, 1, color="0.6"))
                ax.text(i, j, "diverged\n/failed", ha="center", va="center", fontsize=7)
            elif np.isfinite(sigma[j, i]):
                if fails[j, i]:
                    ax.add_patch(plt.Rectangle((i - 0.5, j - 0.5), 1, 1, fill=False, hatch="xx", ec="red"))
                bright = norm is not None and norm(sigma[j, i]) > 0.6  # dark text on viridis' yellows
                ax.text(
                    i,
                    j,
                    f"{sigma[j, i]:.3g}",
                    ha="center",
                    va="center",
                    fontsize=8,
                    color="k" if bright else "w",
                )
    ax.set_xticks(range(len(xs)), [_label(v) for v in xs])
    ax.set_yticks(range(len(ys)), [_label(v) for v in ys])
    ax.set_xlabel(x)
    ax.set_ylabel(y)
    rest = [a for a in grid if a not in (x, y) and len(grid[a]) > 1]
    worst = f" (worst over {', '.join(rest)})" if rest else ""
    ax.set_title(f"{title}: sigma [N]{worst}\nred hatch: fails EN 50367", fontsize=9)
    if norm is not None:
        fig.colorbar(image, ax=ax, label=r"$\sigma$ [N]")
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def axis_figure(
    grid: dict[str, list], rows: list[dict], x: str, title: str, path: Path, statistics: str = "raw"
) -> Path | None:
    """sigma against the grid's only varied parameter."""
    ok = [r for r in rows if _ok(r)]
    if not ok:
        return None
    fig, ax = plt.subplots(figsize=(7, 4), constrained_layout=True)
    labels = [_label(v) for v in grid[x]]
    sigma_key = FORCE_COLUMNS[statistics][1]
    sd = [next((_value(r, sigma_key) for r in ok if _same(r.get(x), v)), math.nan) for v in grid[x]]
    ax.plot(range(len(labels)), sd, "o-")
    ax.set_xticks(range(len(labels)), labels)
    ax.set_yscale("log")
    ax.set_xlabel(x)
    ax.set_ylabel(r"$\sigma$ [N]")
    ax.set_title(title)
    ax.grid(True, alpha=0.3)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _fmt(value: Any) -> str:
    if isinstance(value, bool):
        return "yes" if value else "**no**"
    if isinstance(value, float):
        return f"{value:.4g}"
    if value is None:
        return ""
    return _label(value)


def write_report(spec: Spec, rows: list[dict], out: Path, note: str = "") -> Path:
    """``out/report.md`` and its PNGs (``out/*.png``) from the campaign's rows."""
    out = Path(out)
    for old in out.glob("fig_*.png"):
        old.unlink()
    by_status: dict[str, int] = {}
    for r in rows:
        by_status[r["status"]] = by_status.get(r["status"], 0) + 1
    lines = [
        f"# Campaign `{spec.name}`",
        "",
        f"{len(rows)} runs: " + ", ".join(f"{n} {s}" for s, n in sorted(by_status.items())) + ". "
        f"Measures over {spec.window_text()}.",
        "",
        "Fixed: " + (", ".join(f"`{k}={_label(v)}`" for k, v in spec.fixed.items()) or "nothing") + ".",
        "",
    ]
    for gi, grid in enumerate(spec.grids):
        lines.append(
            f"- grid {gi + 1}: "
            + " x ".join(f"`{k}` [{', '.join(_label(v) for v in vs)}]" for k, vs in grid.items())
        )
    lines += [
        "",
        "EN 50367 criteria (marked in the figures): sigma <= 0.3 Fm and Fm - 3 sigma > 0, "
        "with Fm and sigma the mean and standard deviation of the contact force over the window"
        + (" (20 Hz low-pass, EN 50318)." if spec.statistics == "en50318" else " (unfiltered)."),
        "",
    ]
    if note:
        lines += [note, ""]
    keys = grid_keys(spec)
    for gi, grid in enumerate(spec.grids):
        mine = [r for r in rows if r["key"] in keys[gi]]
        varied = [a for a in grid if len(grid[a]) > 1]
        tag = f"grid {gi + 1}"
        if SPEED in varied:
            path = speed_figure(
                grid, mine, f"{spec.name}, {tag}", out / f"fig_{gi + 1}_speed.png", spec.statistics
            )
            if path:
                lines += [f"## {tag}: quality against speed", "", f"![{tag} speed]({path.name})", ""]
        # The map: the first two varied parameters other than the speed, else speed x the other one.
        others = [a for a in varied if a != SPEED]
        if len(varied) >= 2:
            x, y = (others[0], others[1]) if len(others) >= 2 else (SPEED, others[0])
            path = robustness_map(
                grid,
                mine,
                x,
                y,
                f"{spec.name}, {tag}",
                out / f"fig_{gi + 1}_{_slug(x)}_{_slug(y)}.png",
                spec.statistics,
            )
            lines += [f"## {tag}: robustness map, {x} x {y}", "", f"![{tag} map]({path.name})", ""]
        elif len(varied) == 1 and SPEED not in varied:
            path = axis_figure(
                grid,
                mine,
                varied[0],
                f"{spec.name}, {tag}",
                out / f"fig_{gi + 1}_{_slug(varied[0])}.png",
                spec.statistics,
            )
            if path:
                lines += [f"## {tag}: sigma against {varied[0]}", "", f"![{tag}]({path.name})", ""]
    axes = spec.axes
    cols = [*axes, *(a for a in ("law", SPEED) if a not in axes)]
    mean_key, sigma_key, min_key, loss_key = FORCE_COLUMNS[spec.statistics]
    measures = [
        (mean_key, "Fm [N]"),
        (sigma_key, "sigma [N]"),
        (min_key, "Fm-3sigma [N]"),
        (loss_key, "loss [%]"),
        ("tracking_rms", "tracking RMS [N]"),
        ("stiffness_rel_rms_percent", "k_hat err [%]"),
        ("u_max_abs", "max abs u [N]"),
        ("en50367_sigma_ok", "sigma <= 0.3 Fm"),
        ("en50367_min_ok", "Fm-3sigma > 0"),
    ]
    if spec.statistics == "en50318":
        measures += [
            ("du_dt_max_abs", "max abs du/dt [N/s]"),
            ("uplift_max_mm", "max uplift [mm]"),
            ("force_hat_error_percent", "F_hat err [% of sigma_F]"),
        ]
        # Measured since a later version: shown where the runs have them (older reports unchanged).
        later = (
            ("worst_span_loss_percent", "worst span's loss [%]"),
            ("saturation_percent", "saturated [%]"),
        )
        measures += [(m, label) for m, label in later if any(r.get(m) not in (None, "") for r in rows)]
    table = []
    for r in rows:
        status = r["status"] if _ok(r) else f"{r['status']}: {r.get('reason', '')}"
        table.append([_fmt(r.get(c)) for c in cols] + [status] + [_fmt(r.get(m)) for m, _ in measures])
    header = [*cols, "status", *(m[1] for m in measures)]
    align = [markdown.LEFT] * (len(cols) + 1) + [markdown.RIGHT] * len(measures)
    lines += ["## All runs", "", markdown.table(header, table, align)]
    path = out / "report.md"
    path.write_text("\n".join(lines) + "\n")
    return path
