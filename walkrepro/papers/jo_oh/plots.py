"""Paper III's key signals, for viewers of a run (``walkrepro export --rerun``): each
foot's height and vertical velocity against the references of the impedance law (Eqs. 1-3)
and its normal force, measured and the QP's."""

from walkrepro.present.plots import Plot, Series

_S = "/controller/signals."

PLOTS = (
    Plot(
        "foot_z",
        "foot height z",
        "m",
        tuple(
            Series(f"{_S}{side}_{name}", f"{side} {label}")
            for side in ("left", "right")
            for name, label in (("z", "z"), ("z_d", "z desired"), ("z_m", "z impedance"))
        ),
    ),
    Plot(
        "foot_vz",
        "foot vertical velocity",
        "m/s",
        tuple(Series(f"{_S}{side}_vz", f"{side} v_z") for side in ("left", "right")),
    ),
    Plot(
        "foot_force",
        "foot normal force",
        "N",
        tuple(
            Series(f"{_S}{side}_{name}", f"{side} {label}")
            for side in ("left", "right")
            for name, label in (("fz", "f_z (F/T)"), ("fz_qp", "f_z (QP)"))
        ),
    ),
    Plot(
        "switches",
        "swing foot (0 left, 1 right, -1 none) and impedance switches (1 on)",
        "1",
        (
            Series(_S + "swing_foot", "swing foot"),
            Series(_S + "left_impedance_on", "left impedance on"),
            Series(_S + "right_impedance_on", "right impedance on"),
        ),
    ),
)
