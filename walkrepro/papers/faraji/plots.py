"""Paper II's key signals, for viewers of a run (``walkrepro export --rerun``): the
time-projection footstep adjustment (Eqs. 15-18) and the pelvis speed."""

from walkrepro.present.plots import Plot, Series

_S = "/controller/signals."

PLOTS = (
    Plot(
        "footstep",
        "footstep adjustment",
        "m",
        (Series(_S + "footstep_raw", "footstep (raw)"), Series(_S + "footstep", "footstep")),
    ),
    Plot(
        "pelvis_speed",
        "pelvis speed in the world",
        "m/s",
        (Series("/sim/state.qvel[0]", "forward (x)"), Series("/sim/state.qvel[1]", "lateral (y)")),
    ),
    Plot("phase", "gait phase (-1 before walking)", "1", (Series(_S + "phase", "phase"),)),
)
