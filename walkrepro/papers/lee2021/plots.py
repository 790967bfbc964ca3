"""Paper I's key signals, for viewers of a run (``walkrepro export --rerun``): the E-FSM
state (Table I), the CoM x_m, the capture point (Eq. 2) and the CoP (Eq. 3) along x of O_w."""

from walkrepro.present.plots import Plot, Series

_S = "/controller/signals."

PLOTS = (
    Plot(
        "efsm_state",
        "E-FSM state (0 SSD, 1 SSA, 2 DS) and support (1 left, -1 right, 0 both)",
        "1",
        (Series(_S + "efsm_phase", "E-FSM state"), Series(_S + "fsm_state", "support")),
    ),
    Plot(
        "capture_point",
        "CoM x_m, capture point and CoP along x of O_w",
        "m",
        (
            Series(_S + "com_w[0]", "x_m"),
            Series(_S + "cp_w", "x_CP"),
            Series(_S + "cp_ref_w", "x_CP ref"),
            Series(_S + "x_s_w", "x_s"),
            Series(_S + "xp_des_w", "x_p des"),
            Series(_S + "cop_exp_w[0]", "x_p expected"),
        ),
    ),
    Plot(
        "cop_world",
        "CoP along x of the world",
        "m",
        (
            Series(_S + "cop_exp_world[0]", "expected"),
            Series(_S + "cop_meas_world[0]", "measured"),
        ),
    ),
)
