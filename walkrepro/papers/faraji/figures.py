"""Figures that redraw the faraji paper's plots from a run's log (Paper II, Figs. 13-20).

Each function draws what the run has: a figure that does not apply to a run (e.g. the
drag figure for a push run) returns no files.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from walkrepro.evaluation.metrics import LogData, NotMeasurable
from walkrepro.papers.faraji.metrics import (
    _feet_relative,
    _phase_times,
    _stride_speed,
    corrective_band,
    corrective_steps,
    landings,
)
from walkrepro.present.figures import CompareFn, FigureFn, style
from walkrepro.present.figures.style import save

ERROR_NAMES = ("e₁ = p − f [m]", "e₂ = p − s [m]", "ė₁ [m/s]", "ė₂ [m/s]")


def _is_tp(d: LogData) -> bool:
    return d.spec.controller.type == "timeprojection"


def _mark_disturbances(ax: plt.Axes, d: LogData) -> None:
    for dist in d.spec.disturbances:
        ax.axvspan(
            dist.start,
            dist.start + dist.duration,
            color=style.PALETTE[3],
            alpha=0.15,
            label=f"{dist.name} ({dist.force[0]:+.0f} N)",
        )


def fig13_gains(d: LogData, out_dir: Path) -> list[Path]:
    """Fig. 13: time-projection gains over the phase (torque table A, footstep table B)."""
    if not _is_tp(d):
        return []
    from walkrepro.papers.faraji.controller import (
        TimeProjectionController,
        TimeProjectionParams,
    )
    from walkrepro.sim.robot import load_robot

    ctrl = TimeProjectionController()
    ctrl.reset(load_robot(d.spec.robot), TimeProjectionParams(**d.spec.controller.params), 0.002)
    tp = ctrl.tp
    sag = [0, 2, 4, 6]
    fig, ax = plt.subplots(1, 3, figsize=(14, 4))
    n = int(0.9 * len(tp.phases))  # the torque gains blow up near T (note §7)
    for j, name in zip(sag, ERROR_NAMES, strict=True):
        ax[0].plot(tp.phases[:n], tp.torque_gains[:n, 0, j], label=name)
        ax[1].plot(tp.phases, tp.footstep_gains[:, 0, j], label=name)
        ax[2].plot(tp.phases, ctrl.rel_gains[:, 0, j], label=name)
    ax[0].set_title("A: hip torque gains K_tp\n(constant term, x) [Nm/m]")
    ax[1].set_title("B: footstep gains Δf(T)\n(stance frame) [m/m]")
    ax[2].set_title("used: Δ(f − p)(T) gains\n(attack angle) [m/m]")
    for a in ax:
        a.set_xlabel("phase time t [s]")
    style.legend(ax[2])
    return style.save_titled(
        fig, d, "Fig. 13", "time-projection look-up tables", out_dir / "fig13_gains"
    )


def fig14_feet(d: LogData, out_dir: Path) -> list[Path]:
    """Fig. 14: horizontal foot positions relative to the pelvis at phase changes."""
    phases = _phase_times(d)
    if not _is_tp(d) or phases.size < 4 or d.spec.disturbances:
        return []
    rel = _feet_relative(d, phases)
    fig, ax = plt.subplots(1, 1, figsize=(5, 5))
    for j, (name, c) in enumerate((("left", style.PALETTE[0]), ("right", style.PALETTE[1]))):
        ax.plot(rel[:, j, 1], rel[:, j, 0], "o", color=c, alpha=0.6, label=f"{name} foot")
    ax.plot(0, 0, "k+", markersize=12, label="pelvis")
    ax.set_ylim(-0.2, 0.2)
    ax.set_xlabel("y (lateral) [m]")
    ax.set_ylabel("x (forward) [m]")
    ax.set_aspect("equal")
    style.legend(ax)
    return style.save_titled(
        fig, d, "Fig. 14", "feet relative to the pelvis\nat phase changes", out_dir / "fig14_feet"
    )


def _footstep_plot(d: LogData, ax: plt.Axes) -> None:
    ax.plot(d.t, d.qpos[:, 0], "k", label="pelvis x")
    for foot, c in (("left_foot", style.PALETTE[0]), ("right_foot", style.PALETTE[1])):
        steps = [s for s in d.footsteps if s.foot == foot]
        ax.plot(
            [s.t for s in steps],
            [s.position[0] for s in steps],
            "v",
            color=c,
            label=f"{foot} touchdown x",
        )
    _mark_disturbances(ax, d)
    ax.set_ylabel("x [m]")
    style.legend(ax)


def fig16_push(d: LogData, out_dir: Path) -> list[Path]:
    """Figs. 16-17: sagittal pelvis and footsteps around a push, with the adjustments."""
    if not _is_tp(d) or not d.spec.disturbances or d.spec.disturbances[0].duration > 1.0:
        return []
    fig, ax = plt.subplots(3, 1, figsize=(9, 9), sharex=True)
    _footstep_plot(d, ax[0])
    t, v = d.signal("footstep")
    t_raw, v_raw = d.signal("footstep_raw")
    ax[1].plot(t_raw, v_raw, color="gray", alpha=0.6, label="commanded adjustment (raw)")
    ax[1].plot(t, v, label="commanded adjustment (truncated at 15 cm)")
    _mark_corrective(ax[1], d)
    ax[1].set_ylabel("footstep adjustment [m]")
    style.legend(ax[1])
    _errors(ax[2], d)
    for a, tag, what in zip(
        ax, "abc", ("pelvis and footsteps", "footstep adjustment", "errors"), strict=True
    ):
        style.panel(a, tag, what)
    ax[-1].set_xlabel("time [s]")
    return style.save_titled(fig, d, "Figs. 16–17", "push recovery", out_dir / "fig16_push")


def _mark_corrective(ax: plt.Axes, d: LogData) -> None:
    """The corrective-step rule of ``recovery_steps`` drawn on the adjustment panel: each
    step's realised adjustment (where it put the foot, at the phase change that ends it),
    the undisturbed band μ ∓ 3σ of the steps before the push, and the corrective steps
    (red) with their count."""
    try:
        steps = landings(d)
    except NotMeasurable:
        return
    ax.plot(
        steps.end,
        steps.adjustment,
        "o",
        mfc="none",
        color="k",
        ms=5,
        label="realised (foot at the phase change)",
    )
    t_push = float(d.spec.disturbances[0].start)
    try:
        band = corrective_band(steps.adjustment, steps.start, t_push)
    except NotMeasurable:
        return
    ax.axhspan(*band, color=style.PALETTE[2], alpha=0.12, label="undisturbed band μ ∓ 3σ")
    try:
        chosen = corrective_steps(steps.adjustment, steps.start, t_push, band)
        label = f"corrective steps ({len(chosen)})"
    except NotMeasurable as exc:
        chosen, label = [], f"corrective steps: {exc}"
    if d.outcome != "complete":
        chosen, label = [], f"corrective steps: not counted ({d.outcome})"
    ax.plot(
        steps.end[chosen], steps.adjustment[chosen], "o", color=style.PALETTE[3], ms=7, label=label
    )


def _errors(ax: plt.Axes, d: LogData) -> None:
    t, raw = d.signal("e_raw")
    _, dz = d.signal("e_dead_zone")
    if not t.size:
        return
    for j in (0, 1):
        ax.plot(t, raw[:, j], label=f"{ERROR_NAMES[j]} filtered")
        ax.plot(t, dz[:, j], "--", label=f"{ERROR_NAMES[j]} dead-zoned")
    ax.set_ylabel("error [m]")
    style.legend(ax)


def fig18_drag(d: LogData, out_dir: Path) -> list[Path]:
    """Fig. 18: pelvis position and speed under a continuous drag."""
    if not _is_tp(d) or not d.spec.disturbances or d.spec.disturbances[0].duration <= 1.0:
        return []
    fig, ax = plt.subplots(2, 1, figsize=(9, 7), sharex=True)
    _footstep_plot(d, ax[0])
    ts, vs = _stride_speed(d)
    ax[1].plot(ts, vs, label="pelvis speed (stride average)")
    ax[1].axhline(0.2, color="gray", linestyle=":", label="paper: ±0.2 m/s")
    ax[1].axhline(-0.2, color="gray", linestyle=":")
    _mark_disturbances(ax[1], d)
    ax[1].set_ylabel("speed [m/s]")
    ax[1].set_xlabel("time [s]")
    style.legend(ax[1])
    return style.save_titled(
        fig, d, "Fig. 18", "emergent walking under a drag", out_dir / "fig18_drag"
    )


def fig19_walk(d: LogData, out_dir: Path) -> list[Path]:
    """Fig. 19: trajectories of walking at a commanded speed."""
    speed = float(d.spec.controller.params.get("speed", 0.0)) if _is_tp(d) else 0.0
    if speed == 0.0:
        return []
    fig, ax = plt.subplots(2, 1, figsize=(9, 7), sharex=True)
    _footstep_plot(d, ax[0])
    ax[0].plot(
        d.t, speed * np.clip(d.t - 0.5, 0, None), ":", color="gray", label=f"{speed} m/s reference"
    )
    ts, vs = _stride_speed(d)
    ax[1].plot(ts, vs, label="pelvis speed (stride average)")
    ax[1].axhline(speed, color="gray", linestyle=":", label="command")
    ax[1].set_ylabel("speed [m/s]")
    ax[1].set_xlabel("time [s]")
    style.legend(ax[0])
    style.legend(ax[1])
    return style.save_titled(fig, d, "Fig. 19", f"walking at {speed} m/s", out_dir / "fig19_walk")


def fig20_ankle(d: LogData, out_dir: Path) -> list[Path]:
    """Fig. 20: pull force and pelvis displacement of the standing stiffness test."""
    if d.spec.name != "ankle_stiffness" and d.spec.controller.type != "posture":
        return []
    if not d.spec.disturbances:
        return []
    xfrc = d.inputs_xfrc
    t_in = np.arange(len(xfrc)) * d.spec.sim.timestep
    force = np.array([sum(w[0] for w in x.values()) for x in xfrc])
    fig, ax = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    ax[0].plot(t_in, force, color=style.PALETTE[3], label="pull at the neck, x")
    ax[0].set_ylabel("force [N]")
    ax[1].plot(d.t, d.qpos[:, 0] - d.qpos[0, 0], label="pelvis x displacement")
    ax[1].set_ylabel("[m]")
    ax[1].set_xlabel("time [s]")
    for a in ax:
        style.legend(a)
    return style.save_titled(fig, d, "Fig. 20", "standing pull test", out_dir / "fig20_ankle")


def signals(d: LogData, out_dir: Path) -> list[Path]:
    """Closed-loop signals: errors raw and dead-zoned, attack angle, adaptive lift."""
    if not _is_tp(d):
        return []
    fig, ax = plt.subplots(3, 1, figsize=(9, 8), sharex=True)
    _errors(ax[0], d)
    for name in ("attack_angle", "theta_hat", "pelvis_pitch"):
        t, v = d.signal(name)
        ax[1].plot(t, v, label=f"{name} [rad]")
    style.legend(ax[1])
    t, v = d.signal("adaptive_lift")
    ax[2].plot(t, v, label="adaptive lift (Eq. 29) [m]")
    style.legend(ax[2])
    ax[-1].set_xlabel("time [s]")
    return style.save_titled(
        fig, d, "", "time-projection controller signals (no paper figure)", out_dir / "signals"
    )


def compare_feet(a: LogData, b: LogData, out_dir: Path) -> list[Path]:
    """Fig. 14 side by side: feet at phase changes of two in-place runs."""
    fig, axes = plt.subplots(1, 2, figsize=(10, 5), sharex=True, sharey=True)
    for ax, d in zip(axes, (a, b), strict=True):
        phases = _phase_times(d)
        if phases.size < 4:
            continue
        rel = _feet_relative(d, phases)
        ax.plot(rel[:, 0, 1], rel[:, 0, 0], "o", alpha=0.6, label="left")
        ax.plot(rel[:, 1, 1], rel[:, 1, 0], "o", alpha=0.6, label="right")
        ax.set_title(d.spec.name)
        ax.set_xlabel("y [m]")
    style.legend(axes[1])
    axes[0].set_ylabel("x [m]")
    style.title(
        fig,
        a.spec.paper.key,
        "Fig. 14",
        "feet relative to the pelvis at phase changes",
        f"{a.spec.name} vs {b.spec.name}",
    )
    return save(fig, out_dir / f"fig14_compare_{a.spec.name}_vs_{b.spec.name}")


#: Figures drawn from one run.
FIGURES: list[FigureFn] = [
    fig13_gains,
    fig14_feet,
    fig16_push,
    fig18_drag,
    fig19_walk,
    fig20_ankle,
    signals,
]
#: Figures comparing two runs (`walkrepro plot RUN_A RUN_B`).
COMPARE: list[CompareFn] = [compare_feet]
