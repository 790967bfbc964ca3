"""The overview every run gets: pelvis motion, foot loads, disturbances and falls.

Not a paper figure; it is the first thing to look at when a reproduction misbehaves.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from walkrepro.evaluation.metrics import FOOT_BODIES, GRAVITY, LogData
from walkrepro.present.figures import style
from walkrepro.present.figures.style import save


def overview(d: LogData, out_dir: Path) -> list[Path]:
    """Pelvis position, foot normal forces with touchdowns, applied external forces."""
    fig, axes = plt.subplots(3, 1, figsize=(8, 8), sharex=True)
    _pelvis(axes[0], d, "")
    _feet(axes[1], d)
    _external(axes[2], d)
    axes[-1].set_xlabel("time [s]")
    style.title(
        fig,
        "walkrepro",
        "",
        f"run overview, not a paper figure (outcome: {d.outcome})",
        d.spec.name,
    )
    return save(fig, out_dir / "overview")


def compare(a: LogData, b: LogData, out_dir: Path) -> list[Path]:
    """Pelvis position of two runs on shared axes."""
    fig, ax = plt.subplots(1, 1, figsize=(8, 4))
    _pelvis(ax, a, f"{a.spec.name} ")
    _pelvis(ax, b, f"{b.spec.name} ", linestyle="--")
    ax.set_xlabel("time [s]")
    style.title(
        fig,
        "walkrepro",
        "",
        "pelvis position, not a paper figure",
        f"{a.spec.name} vs {b.spec.name}",
    )
    return save(fig, out_dir / f"compare_{a.spec.name}_vs_{b.spec.name}")


def _pelvis(ax: plt.Axes, d: LogData, prefix: str, linestyle: str = "-") -> None:
    for i, axis in enumerate("xyz"):
        ax.plot(d.t, d.qpos[:, i], linestyle=linestyle, label=f"{prefix}pelvis {axis}")
    _mark_fall(ax, d)
    ax.set_ylabel("position [m]")
    style.legend(ax)


def _feet(ax: plt.Axes, d: LogData) -> None:
    for foot in FOOT_BODIES:
        ax.plot(d.contact_t, d.foot_normal_force(foot), label=f"{foot} normal force")
    steps = d.footsteps
    if steps:
        ax.plot([s.t for s in steps], np.zeros(len(steps)), "kv", label="touchdown")
    ax.axhline(d.robot_mass * GRAVITY, color="gray", linestyle=":", label="robot weight")
    ax.set_ylabel("force [N]")
    style.legend(ax)


def _external(ax: plt.Axes, d: LogData) -> None:
    xfrc = d.inputs_xfrc
    dt = d.spec.sim.timestep
    t = np.arange(len(xfrc)) * dt
    mag = np.array([sum(float(np.linalg.norm(w[:3])) for w in x.values()) for x in xfrc])
    ax.plot(t, mag, color=style.PALETTE[3], label="|external force|")
    ax.set_ylabel("force [N]")
    style.legend(ax)


def _mark_fall(ax: plt.Axes, d: LogData) -> None:
    for e in d.events:
        if e.get("kind") == "fall":
            ax.axvline(e["t"], color=style.PALETTE[3], linestyle="--", label="fall")
