"""Figures that redraw the jo_oh paper's plots (Figs. 4–7) from a run's log.

All plots centre on the right foot's step onto the obstacle (§IV: the obstacle lies in the
middle of the right foot's path). Signals come from ``/controller/signals`` (the
controller's own measurements and references, as in the paper) and ``/sim/contacts``.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from walkrepro.evaluation.metrics import GRAVITY, LogData
from walkrepro.papers.jo_oh.metrics import CONTACT_FORCE, OBSTACLE_GLOB
from walkrepro.present.figures import CompareFn, FigureFn, style
from walkrepro.present.figures.style import save

FOOT = "right"
#: Time shown before and after the first obstacle contact [s] (Figs. 4–7 span ~1.5 s).
BEFORE, AFTER = 0.6, 1.0
#: Swing-foot signal value meaning "right foot swings" (footsteps.RIGHT).
RIGHT_SWING = 1.0
#: (signal suffix, label, unit) of each axis of Figs. 5–7.
AXES = {
    "z": ("z", "z-axis", "m"),
    "roll": ("roll", "x-axis", "rad"),
    "pitch": ("pitch", "y-axis", "rad"),
}
#: Signal names of the foot's current state per axis: position, velocity, acceleration.
CURRENT = {
    "z": ("z", "vz", "az"),
    "roll": ("roll", "wx", "alphax"),
    "pitch": ("pitch", "wy", "alphay"),
}


def _contact_time(d: LogData) -> float:
    """First time an obstacle pushes the right foot, else the middle of the run [s]."""
    force = np.linalg.norm(d.contact_wrench(f"{FOOT}_foot/{OBSTACLE_GLOB}")[:, :3], axis=1)
    idx = np.flatnonzero(force > CONTACT_FORCE)
    if idx.size:
        return float(d.contact_t[idx[0]])
    return float(d.t[-1] / 2) if d.t.size else 0.0


def _window(d: LogData, t0: float) -> tuple[float, float]:
    return t0 - BEFORE, t0 + AFTER


def _shade_stance(ax: plt.Axes, d: LogData, lo: float, hi: float) -> None:
    """Shade the right foot's planned stance; label double support DP (Fig. 4)."""
    t, swing = d.signal("swing_foot")
    if not t.size:
        return
    stance = swing != RIGHT_SWING
    double = swing < 0
    ax.fill_between(t, 0, 1, where=stance, color="0.9", transform=ax.get_xaxis_transform(), lw=0)
    edges = np.flatnonzero(np.diff(double.astype(int)) == 1)
    for e in edges:
        if lo <= t[e] <= hi:
            ax.text(t[e], 0.95, "DP", transform=ax.get_xaxis_transform(), fontsize=7, va="top")


def _force(d: LogData) -> np.ndarray:
    """Vertical contact force on the right foot from every world geom [N]."""
    return d.foot_normal_force(f"{FOOT}_foot")


def _fig4(runs: list[tuple[LogData, str, str]], out: Path) -> list[Path]:
    first = runs[0][0]
    t0 = _contact_time(first)
    lo, hi = _window(first, t0)
    fig, ax = plt.subplots(figsize=(8, 4))
    _shade_stance(ax, first, lo, hi)
    for d, label, fmt in runs:
        ax.plot(d.contact_t, _force(d), fmt, label=label)
    weight = first.robot_mass * GRAVITY
    ax.axhline(weight, color=style.PALETTE[2], linestyle=":", label=f"robot weight {weight:.0f} N")
    ax.set_xlim(lo, hi)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("right foot contact force z [N]")
    style.legend(ax)
    style.title(
        fig,
        first.spec.paper.key,
        "Fig. 4",
        "contact force (shaded: right stance, DP: double support)",
        " vs ".join(d.spec.name for d, _, _ in runs),
    )
    return save(fig, out)


def _fig_axis(
    runs: list[tuple[LogData, str, str]], axis: str, fig_name: str, out: Path
) -> list[Path]:
    """Position, velocity, acceleration of one foot axis: current, desired, modified (Figs. 5–7)."""
    sig, name, unit = AXES[axis]
    first = runs[0][0]
    lo, hi = _window(first, _contact_time(first))
    fig, axes = plt.subplots(3, 1, figsize=(8, 9), sharex=True)
    derivs = ("", "_dot", "_ddot")
    units = (unit, f"{unit}/s", f"{unit}/s²")
    titles = ("position" if axis == "z" else "orientation", "velocity", "acceleration")
    for k, ax in enumerate(axes):
        for d, label, fmt in runs:
            t, v = d.signal(f"{FOOT}_{CURRENT[axis][k]}")
            ax.plot(t, v, fmt, label=f"current {label}")
        # References of the first run (the impedance run when comparing).
        t, v = first.signal(f"{FOOT}_{sig}{derivs[k]}_d")
        ax.plot(t, v, "--", color=style.PALETTE[2], label="desired")
        t, v = first.signal(f"{FOOT}_{sig}{derivs[k]}_m")
        ax.plot(t, v, ":", color=style.PALETTE[3], label="modified desired")
        ax.set_ylabel(f"{name} {titles[k]} [{units[k]}]")
        style.legend(ax)
        style.panel(ax, "abc"[k], titles[k])
        _shade_stance(ax, first, lo, hi)
    for ax in axes:
        _fit_y(ax, lo, hi)
    axes[-1].set_xlim(lo, hi)
    axes[-1].set_xlabel("time [s]")
    style.title(
        fig,
        first.spec.paper.key,
        fig_name,
        f"right foot {name}",
        " vs ".join(d.spec.name for d, _, _ in runs),
    )
    return save(fig, out)


def _fit_y(ax: plt.Axes, lo: float, hi: float) -> None:
    """Scale the y axis to the lines' values inside the time window [lo, hi] [s]."""
    values = [
        y[(x >= lo) & (x <= hi)]
        for x, y in (line.get_data() for line in ax.get_lines())
        if np.size(x) > 1
    ]
    values = [v for v in values if v.size]
    if not values:
        return
    y_min = min(float(np.min(v)) for v in values)
    y_max = max(float(np.max(v)) for v in values)
    pad = 0.05 * (y_max - y_min or 1.0)
    ax.set_ylim(y_min - pad, y_max + pad)


def _tilt_axis(d: LogData) -> str:
    """Foot axis the obstacle's tilt acts on: roll for tilt about x, pitch about y, else z."""
    for o in d.spec.world.obstacles:
        if o.tilt_x_deg:
            return "roll"
        if o.tilt_y_deg:
            return "pitch"
    return "z"


def fig4_contact_force(d: LogData, out_dir: Path) -> list[Path]:
    """Fig. 4 of one run: right-foot contact force, robot weight, stance phases."""
    return _fig4([(d, d.spec.name, "C0-")], out_dir / "fig4_contact_force")


def fig5_to_7_foot_motion(d: LogData, out_dir: Path) -> list[Path]:
    """Fig. 5 (z), Fig. 6 (tilt about x) or Fig. 7 (about y) of one run."""
    axis = _tilt_axis(d)
    name = {"z": "Fig. 5", "roll": "Fig. 6", "pitch": "Fig. 7"}[axis]
    paths = _fig_axis(
        [(d, d.spec.name, "C0-")],
        axis,
        name,
        out_dir / f"{name.lower().replace('. ', '')}_foot_{axis}",
    )
    if axis != "z":
        paths += _fig_axis(
            [(d, d.spec.name, "C0-")], "z", "Fig. 5 (z of this run)", out_dir / "fig5_foot_z"
        )
    return paths


def compare_fig4(a: LogData, b: LogData, out_dir: Path) -> list[Path]:
    """Fig. 4: contact force with (a) and without (b) impedance on one plot."""
    return _fig4(
        [(a, a.spec.name, "C0-"), (b, b.spec.name, "C1--")],
        out_dir / f"fig4_contact_force_{a.spec.name}_vs_{b.spec.name}",
    )


def compare_fig5(a: LogData, b: LogData, out_dir: Path) -> list[Path]:
    """Fig. 5(a)–(c) (or 6/7 for tilts): current with and without, desired, modified desired."""
    axis = _tilt_axis(a)
    name = {"z": "Fig. 5", "roll": "Fig. 6", "pitch": "Fig. 7"}[axis]
    return _fig_axis(
        [(a, a.spec.name, "C0-"), (b, b.spec.name, "C1-")],
        axis,
        name,
        out_dir / f"{name.lower().replace('. ', '')}_foot_{axis}_{a.spec.name}_vs_{b.spec.name}",
    )


#: Figures drawn from one run.
FIGURES: list[FigureFn] = [fig4_contact_force, fig5_to_7_foot_motion]
#: Figures comparing two runs (`walkrepro plot RUN_A RUN_B`).
COMPARE: list[CompareFn] = [compare_fig4, compare_fig5]
