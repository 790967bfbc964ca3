"""What the point-contact ground law (walkrepro/sim/contact_law.py) costs per physics step.

Two COMAN-sized soles on the lab's 1 cm grid (200 points each) stand on the ground under a
14 kg block each; the script times MuJoCo's ``mj_step`` with the law applied against the same
model stepping without it (its own contact then off: the block falls freely, which costs
MuJoCo about the same). The difference is what the law adds to every 0.5 ms step of a run.
Then ``robots/coman_lab`` standing at its home keyframe on the law, at Paper II's 0.25 ms:
the compiled callback (one law applied, no Python in a step), the Python dispatcher (two
laws applied at once; what every step paid before) and no law.

Run: ``python benchmarks/contact_law.py`` (a minute). Absolute times drift with the
machine's load; compare the columns of one run, alternating.
"""

from __future__ import annotations

import contextlib
import time

import mujoco

from walkrepro.sim.contact_law import GroundContact, PointContactLaw, applied, from_model, sole_grid
from walkrepro.sim.robot import load_robot

LAB = PointContactLaw(27818.0, 0.3, 1e4, 10.0, 0.9)
POINTS = sole_grid((-0.095, 0.095), (-0.045, 0.045), -0.02, 0.01)
SOLES = {"left": POINTS, "right": POINTS}


def model() -> mujoco.MjModel:
    """Two free soles side by side, resting on the ground."""
    bodies = "".join(
        f'<body name="{name}" pos="0 {y} 0.02"><freejoint/>'
        '<geom type="box" size="0.095 0.045 0.02" mass="14" contype="0" conaffinity="0"/></body>'
        for name, y in (("left", 0.1), ("right", -0.1))
    )
    return mujoco.MjModel.from_xml_string(
        f'<mujoco><option timestep="0.0005"/><size nuserdata="{GroundContact.userdata_size(SOLES)}"/>'
        f'<worldbody><geom type="plane" size="1 1 1" contype="0" conaffinity="0"/>{bodies}'
        "</worldbody></mujoco>"
    )


def _nothing(m: mujoco.MjModel, d: mujoco.MjData) -> None:
    """A passive callback that does nothing: what entering Python from MuJoCo costs."""


def per_step(mode: str, steps: int = 4000) -> float:
    """Mean wall time of one mj_step [µs] after 0.5 s of settling on the law.

    ``mode``: "law" (the law applied), "empty" (a Python callback that does nothing) or
    "none" (no callback).
    """
    m = model()
    d = mujoco.MjData(m)
    with applied(GroundContact(m, LAB, SOLES)):
        for _ in range(1000):
            mujoco.mj_step(m, d)
        if mode == "law":
            return _time(m, d, steps)
    mujoco.set_mjcb_passive(_nothing if mode == "empty" else None)
    try:
        return _time(m, d, steps)
    finally:
        mujoco.set_mjcb_passive(None)


def _time(m: mujoco.MjModel, d: mujoco.MjData, steps: int) -> float:
    start = time.perf_counter()
    for _ in range(steps):
        mujoco.mj_step(m, d)
    return (time.perf_counter() - start) / steps * 1e6


def coman_step(mode: str, steps: int = 2000) -> float:
    """Mean wall time of one mj_step [µs] of coman_lab standing at home after 0.25 s.

    ``mode``: "compiled" (its law alone), "dispatcher" (its law and a second one) or "none".
    """
    robot = load_robot("coman_lab")
    m = robot.mj_model
    m.opt.timestep = 0.00025  # Paper II's specs' physics step
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
    d.ctrl[:] = robot.home_ctrl
    with contextlib.ExitStack() as laws:
        if mode != "none":
            laws.enter_context(applied(from_model(m)))
        if mode == "dispatcher":
            laws.enter_context(applied(GroundContact(model(), LAB, SOLES)))
        for _ in range(1000):
            mujoco.mj_step(m, d)
        return _time(m, d, steps)


if __name__ == "__main__":
    modes = ("law", "empty", "none")
    rounds = [[per_step(mode) for mode in modes] for _ in range(5)]
    law, empty, none = (min(r[i] for r in rounds) for i in range(len(modes)))
    print(f"mj_step with the law, 2 × 200 points: {law:.1f} µs")
    print(f"mj_step, an empty Python callback:   {empty:.1f} µs")
    print(f"mj_step, no callback:                {none:.1f} µs")
    print(
        f"the law adds {law - none:.1f} µs per 0.5 ms step ({empty - none:.1f} µs entering Python)"
    )
    kinds = ("compiled", "dispatcher", "none")
    rounds = [[coman_step(kind) for kind in kinds] for _ in range(5)]
    for i, kind in enumerate(kinds):
        best = min(r[i] for r in rounds)
        print(f"coman_lab standing, {kind:10s}: {best:.1f} µs per 0.25 ms step")
