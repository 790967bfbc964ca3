"""Figures that redraw the lee2021 paper's plots from a run's log.

Frames as in the paper: O_g (global: the midpoint of the feet's initial positions, which
is walkrepro's world origin at ``home``) for Figs. 7, 10 and 12(c); O_w (support-foot
frame of the E-FSM) for Figs. 12(b) and (d). Each function returns ``[]`` when the run
lacks what the figure shows (e.g. Fig. 12 without a push).
"""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from walkrepro.evaluation.metrics import LogData
from walkrepro.papers.lee2021.metrics import switch_torque_jumps
from walkrepro.present.figures import CompareFn, FigureFn, style
from walkrepro.present.figures.style import save
from walkrepro.sim.robot import leg_actuators

#: Fig. 14 shows the first steps: the paper's robot falls after t ≈ 1 s without ε [s].
FIG14_SPAN = 2.5
#: Colours of the E-FSM switches marked in Fig. 14, by (from, to) phase (efsm_phase codes).
SWITCH_COLOURS = {
    (2.0, 0.0): style.PALETTE[0],
    (0.0, 1.0): style.PALETTE[2],
    (1.0, 2.0): style.PALETTE[3],
    # SSD → SSA → DS within one tick (fsm_step: the CoM already stopped and the CP already
    # at x_s − r when SSD begins), logged as SSD → DS.
    (0.0, 2.0): style.PALETTE[4],
}
PHASE_NAMES = style.EFSM_STATES
#: Colours of the quantities Figs. 7 and 12 share, the same in every panel.
COLOURS = {
    "CoM": style.PALETTE[0],
    "swing foot": style.PALETTE[1],
    "supporting foot": style.PALETTE[2],
    "swing foot reference": style.PALETTE[7],
    "reference CoP": style.PALETTE[4],
}


def _sig(d: LogData, name: str) -> tuple[np.ndarray, np.ndarray]:
    return d.signal(name)


def _swing_only(d: LogData, values: np.ndarray, foot: float | None = None) -> np.ndarray:
    """Mask (NaN) samples in DS, or where ``foot`` (1 right, −1 left) is not swinging."""
    _, swing = _sig(d, "swing_foot")
    keep = swing != 0 if foot is None else swing == foot
    out = np.array(values, dtype=float)
    out[~keep] = np.nan
    return out


def _push_span(ax: plt.Axes, d: LogData) -> None:
    on = [e["t"] for e in d.events if e.get("kind") == "disturbance_on"]
    off = [e["t"] for e in d.events if e.get("kind") == "disturbance_off"]
    for i, t0 in enumerate(on):
        t1 = off[i] if i < len(off) else d.t[-1]
        ax.axvspan(t0, t1, color="0.88", label="push" if i == 0 else None)


def fig7_com_and_feet(d: LogData, out_dir: Path) -> list[Path]:
    """Fig. 7: CoM, swing and support foot in x (a), y with the reference CoP (b), swing z (c)."""
    t, com = _sig(d, "com_world")
    if not t.size:
        return []
    _, sw = _sig(d, "swing_pos_world")
    _, ref = _sig(d, "swing_ref_world")
    _, sup = _sig(d, "support_pos_world")
    _, xp = _sig(d, "xp_des_world")
    c = COLOURS
    fig, axes = plt.subplots(3, 1, figsize=(9, 9), sharex=True)
    for ax, i, axis in ((axes[0], 0, "x"), (axes[1], 1, "y")):
        ax.plot(t, com[:, i], color=c["CoM"], label="CoM")
        ax.plot(t, _swing_only(d, sw[:, i]), color=c["swing foot"], label="swing foot")
        ax.plot(t, sup[:, i], color=c["supporting foot"], label="supporting foot", linewidth=0.8)
        ax.plot(
            t,
            _swing_only(d, ref[:, i]),
            "--",
            color=c["swing foot reference"],
            label="swing foot reference",
        )
        ax.set_ylabel(f"{axis}_g [m]")
    axes[1].plot(t, xp[:, 1], ":", color=c["reference CoP"], label="reference CoP")
    axes[2].plot(t, _swing_only(d, sw[:, 2]), color=c["swing foot"], label="swing foot")
    axes[2].plot(
        t,
        _swing_only(d, ref[:, 2]),
        "--",
        color=c["swing foot reference"],
        label="swing foot reference",
    )
    axes[2].set_ylabel("z_g [m]")
    for ax, tag, what in zip(axes, "abc", ("x in O_g", "y in O_g", "swing height"), strict=True):
        style.panel(ax, tag, what)
        style.legend(ax)
    axes[-1].set_xlabel("time [s]")
    return style.save_titled(
        fig, d, "Fig. 7", "CoM and foot motion in O_g", out_dir / "fig7_com_feet"
    )


def _states(ax: plt.Axes, d: LogData) -> None:
    """The E-FSM state by name (DS, SSD, SSA; ``efsm_phase``) over the support side
    (``fsm_state``), or the support side alone for a log without ``efsm_phase``."""
    t, state = _sig(d, "fsm_state")
    t_phase, phase = _sig(d, "efsm_phase")
    style.support_sides(ax, t, state)
    if t_phase.size:
        style.efsm_states(ax, t_phase, phase)
    else:  # a log written before efsm_phase: the walking state as logged
        ax.step(t, state, where="post", label="walking state")
        ax.set_yticks([-1, 0, 1], ["right support", "DS", "left support"])


def fig8_states(d: LogData, out_dir: Path) -> list[Path]:
    """Fig. 8: E-FSM states by name (DS, SSD, SSA), the support side shaded."""
    t, _ = _sig(d, "fsm_state")
    if not t.size:
        return []
    fig, ax = plt.subplots(1, 1, figsize=(9, 3))
    _states(ax, d)
    style.legend(ax)
    ax.set_xlabel("time [s]")
    return style.save_titled(fig, d, "Fig. 8", "E-FSM states", out_dir / "fig8_states")


def fig10_right_foot(d: LogData, out_dir: Path) -> list[Path]:
    """Fig. 10: right-foot x and its reference (only while it swings) in O_g."""
    if not any(o.name.startswith("obstacle") for o in d.spec.world.obstacles):
        return []
    t, sw = _sig(d, "swing_pos_world")
    _, ref = _sig(d, "swing_ref_world")
    _, swing = _sig(d, "swing_foot")
    from walkrepro.papers.lee2021.metrics import _sole_tracks

    right = _sole_tracks(d)["right"]
    fig, ax = plt.subplots(1, 1, figsize=(9, 4))
    ax.plot(d.t, right[:, 0], label="right foot x")
    ax.plot(t, np.where(swing == 1, ref[:, 0], np.nan), "--", label="reference (swinging)")
    for o in d.spec.world.obstacles:
        ax.axhline(o.position[0] - o.size[0] / 2, color="k", linewidth=0.8, label=f"{o.name} face")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("x_g [m]")
    style.legend(ax)
    return style.save_titled(
        fig, d, "Fig. 10", "right foot against the obstacle", out_dir / "fig10_right_foot"
    )


def fig12_push(d: LogData, out_dir: Path) -> list[Path]:
    """Fig. 12: states (a), CP and x_s − r in O_w (b), y motion in O_g (c), ẋ_m in O_w (d)."""
    if not d.spec.disturbances:
        return []
    t, _ = _sig(d, "fsm_state")
    _, cp = _sig(d, "cp_w")
    _, cp_ref = _sig(d, "cp_ref_w")
    _, com = _sig(d, "com_world")
    _, sw = _sig(d, "swing_pos_world")
    _, sup = _sig(d, "support_pos_world")
    _, ref = _sig(d, "swing_ref_world")
    _, vel = _sig(d, "com_vel_w")
    c = COLOURS
    fig, axes = plt.subplots(4, 1, figsize=(9, 11), sharex=True)
    _states(axes[0], d)
    axes[1].plot(t, cp, label="CP x_CP")
    axes[1].plot(t, cp_ref, "--", label="reference x_s − r")
    axes[1].set_ylabel("x_w [m]")
    axes[2].plot(t, com[:, 1], color=c["CoM"], label="CoM")
    axes[2].plot(t, _swing_only(d, sw[:, 1]), color=c["swing foot"], label="swing foot")
    axes[2].plot(t, sup[:, 1], color=c["supporting foot"], label="supporting foot", linewidth=0.8)
    axes[2].plot(
        t,
        _swing_only(d, ref[:, 1]),
        "--",
        color=c["swing foot reference"],
        label="swing foot reference",
    )
    axes[2].set_ylabel("y_g [m]")
    axes[3].plot(t, vel[:, 0], color=c["CoM"], label="CoM velocity")
    axes[3].set_ylabel("ẋ_w [m/s]")
    whats = ("E-FSM states", "capture point in O_w", "y motion in O_g", "CoM velocity in O_w")
    for ax, tag, what in zip(axes, "abcd", whats, strict=True):
        _push_span(ax, d)
        style.panel(ax, tag, what)
        style.legend(ax)
    axes[-1].set_xlabel("time [s]")
    return style.save_titled(
        fig, d, "Fig. 12", "a push on the upper body during walking", out_dir / "fig12_push"
    )


def _switches(ax: plt.Axes, d: LogData, t_max: float) -> None:
    """Mark the E-FSM state switches (efsm_phase changes) up to ``t_max`` [s]."""
    t, phase = _sig(d, "efsm_phase")
    seen = set()
    for k in np.nonzero(np.diff(phase) != 0)[0] + 1:
        if t[k] > t_max:
            break
        kind = (phase[k - 1], phase[k])
        label = None if kind in seen else "→".join(PHASE_NAMES[p] for p in kind)
        seen.add(kind)
        ax.axvline(t[k], color=SWITCH_COLOURS[kind], linestyle=":", linewidth=1.0, label=label)


def _torques(ax: plt.Axes, d: LogData, t_max: float) -> None:
    """The left leg's reference torques (Fig. 14(a)/(b)), the switches marked, and the
    largest jump at a switch (``switch_torque_jump:left``) circled and labelled."""
    t, tau = _sig(d, "tau_ref")
    model = d.model
    joints = leg_actuators(model, "left_foot")
    keep = t <= t_max
    for j in joints:
        ax.plot(t[keep], tau[keep, j], label=model.actuator(j).name, linewidth=0.9)
    _switches(ax, d, t_max)
    _, phase = _sig(d, "efsm_phase")
    if phase.size == t.size:
        ticks, jumps = switch_torque_jumps(phase, tau, joints)
        shown = t[ticks] <= t_max
        if np.any(shown):
            i = int(np.argmax(np.where(shown, jumps, -np.inf)))
            k = ticks[i]
            j = joints[int(np.argmax(np.abs(tau[k, joints] - tau[k - 1, joints])))]
            span = (tau[k - 1, j], tau[k, j])
            ax.plot([t[k], t[k]], span, color="k", linewidth=2.5, label="largest switch jump")
            ax.annotate(
                f"{jumps[i]:.1f} Nm in one tick ({model.actuator(j).name});"
                f" over the run: {np.max(jumps):.1f} Nm",
                (t[k], float(np.mean(span))),
                xytext=(12, 0),
                textcoords="offset points",
                fontsize="x-small",
                va="center",
                bbox={"boxstyle": "round", "facecolor": "white", "alpha": 0.8, "linewidth": 0},
            )
    ax.set_ylabel("reference torque [Nm]")
    style.legend(ax, fontsize="x-small")


def _epsilon(ax: plt.Axes, d: LogData, t_max: float) -> None:
    """Fig. 14(c): ε (Eq. 23) and the onset ramp this reproduction adds in DS."""
    t, eps = _sig(d, "epsilon")
    keep = t <= t_max
    ax.plot(t[keep], eps[keep], label="ε (§IV-B)")
    _, onset = _sig(d, "epsilon_onset")
    if onset.size == t.size and np.any(onset[keep] < 1.0):
        ax.plot(t[keep], onset[keep], "--", linewidth=0.9, label="ε onset ramp\nin DS (assumed)")
    _switches(ax, d, t_max)
    ax.set_ylabel("ε")
    ax.set_ylim(-0.05, 1.05)
    style.legend(ax, fontsize="x-small")


def fig14_torques(d: LogData, out_dir: Path) -> list[Path]:
    """Fig. 14 for one run: left-leg reference torques and ε over the first steps."""
    t, _ = _sig(d, "epsilon")
    if not t.size or not _sig(d, "tau_ref")[0].size:
        return []
    t_max = min(float(t[-1]), FIG14_SPAN)
    fig, axes = plt.subplots(2, 1, figsize=(12, 6.5), sharex=True)
    _torques(axes[0], d, t_max)
    _epsilon(axes[1], d, t_max)
    style.panel(axes[0], "", "reference torques of the left leg")
    style.panel(axes[1], "", "state-transition parameter ε")
    axes[1].set_xlabel("time [s]")
    return style.save_titled(
        fig,
        d,
        "Fig. 14",
        "left-leg reference torques and ε (dotted: E-FSM switches)",
        out_dir / "fig14_torques",
    )


def fig14_compare(a: LogData, b: LogData, out_dir: Path) -> list[Path]:
    """Fig. 14 (a)(b)(c): left-leg torques of two runs (without and with ε) and ε of the
    second, over the first FIG14_SPAN seconds, the E-FSM switches marked."""
    if not _sig(b, "epsilon")[0].size or not _sig(a, "tau_ref")[0].size:
        return []
    fig, axes = plt.subplots(3, 1, figsize=(12, 10), sharex=True)
    _torques(axes[0], a, FIG14_SPAN)
    _torques(axes[1], b, FIG14_SPAN)
    _epsilon(axes[2], b, FIG14_SPAN)
    titles = (
        f"(a) {a.spec.name}: reference torques of the left leg",
        f"(b) {b.spec.name}: reference torques of the left leg",
        f"(c) {b.spec.name}: state-transition parameter ε",
    )
    for ax, title in zip(axes, titles, strict=True):
        ax.set_title(title, loc="left")
    axes[-1].set_xlabel("time [s]")
    style.title(
        fig,
        a.spec.paper.key,
        "Fig. 14",
        "left-leg reference torques without and with ε (dotted: E-FSM switches)",
        f"{a.spec.name} vs {b.spec.name}",
    )
    return save(fig, out_dir / f"fig14_{a.spec.name}_vs_{b.spec.name}")


def fig15_cop(d: LogData, out_dir: Path) -> list[Path]:
    """Fig. 15: expected CoP (reference torques, Eqs. 18, 22) and measured CoP (F/T) in O_g."""
    t, exp = _sig(d, "cop_exp_world")
    if not t.size:
        return []
    _, meas = _sig(d, "cop_meas_world")
    _, valid = _sig(d, "cop_meas_valid")
    meas = np.where(valid[:, None] > 0, meas, np.nan)
    fig, axes = plt.subplots(3, 1, figsize=(9, 8), sharex=True)
    for ax, i, axis in ((axes[0], 0, "x"), (axes[1], 1, "y")):
        ax.plot(t, exp[:, i], label="expected CoP")
        ax.plot(t, meas[:, i], "--", label="measured CoP (F/T)")
        ax.set_ylabel(f"{axis}_g [m]")
    axes[2].plot(t, np.linalg.norm(exp - meas, axis=1), label="|error|")
    axes[2].set_ylabel("error [m]")
    axes[2].set_ylim(0.0, 0.1)
    for ax, tag, what in zip(axes, "abc", ("x in O_g", "y in O_g", "distance"), strict=True):
        style.panel(ax, tag, what)
        style.legend(ax)
    axes[-1].set_xlabel("time [s]")
    return style.save_titled(fig, d, "Fig. 15", "expected and measured CoP", out_dir / "fig15_cop")


#: Figures drawn from one run.
FIGURES: list[FigureFn] = [
    fig7_com_and_feet,
    fig8_states,
    fig10_right_foot,
    fig12_push,
    fig14_torques,
    fig15_cop,
]
#: Figures comparing two runs (`walkrepro plot RUN_A RUN_B`).
COMPARE: list[CompareFn] = [fig14_compare]
