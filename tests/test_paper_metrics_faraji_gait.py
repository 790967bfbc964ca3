"""Paper II (Faraji et al.) gait-shape metrics on synthetic logs: the foot lift (Fig. 8), the
double support (3LP Model), the lateral bounce, the knee spring compressions (Fig. 7) and the
touchdowns against the fixed timing (Fig. 19), each where the claim holds and where it does
not."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from test_metrics import (
    DT,
    Poser,
    Tick,
    home_sole,
    make_spec,
    measured,
    standing_pairs,
    unmeasurable_reason,
    write_log,
)

from walkrepro.evaluation.metrics import LogData, MetricArgError, check_metric_arg
from walkrepro.papers.faraji.metrics import (
    double_support_fractions,
    foot_swings,
    full_load_knee_compressions,
    lateral_excursions,
    loaded_mask,
    spring_compression,
    touchdown_leads,
)

ROBOT = "coman"
STEP = 0.4  # [s] (Paper II's T)
START = 0.5  # [s] first phase change of the synthetic gait
N_STEPS = 6
FEET = ("left_foot", "right_foot")


def _q(x: float) -> float:
    """``x`` rounded to 0.1 mm, so that the poser's solutions are reused across steps."""
    return round(x, 4)


def _gait_log(
    path: Path,
    ds: float = 0.2,
    lift: float = 0.024,
    bounce: float = 0.022,
    lead: Callable[[int], float] = lambda j: 0.0,
    knee: float | Callable[[float], float] = 0.05,
    robot: str = ROBOT,
    outcome: str = "complete",
    params: dict | None = None,
) -> LogData:
    """An in-place gait: phase changes every 0.4 s from 0.5 s; the foot that swings in step
    j (left for even j) lands ``lead(j)`` [s] before the phase change that ends it; both feet
    carry the weight for ``ds`` of a step after each touchdown, then the swing foot lifts its
    sole centre ``lift`` [m] on a half sine; the pelvis sways laterally ``bounce`` [m] peak
    to peak over a stride; each knee's spring (link − motor) is ``knee`` [rad] (or ``knee(t)``) while its foot
    carries the whole weight, 0 otherwise."""
    poser = Poser(robot)
    model = poser.model
    knees = {
        foot: (
            int(model.jnt_qposadr[model.joint(f"{foot[0]}_knee_motor").id]),
            int(model.jnt_qposadr[model.joint(f"{foot[0]}_knee").id]),
        )
        for foot in FEET
    }
    touchdowns = [START - lead(-1)] + [START + STEP * (j + 1) - lead(j) for j in range(N_STEPS)]
    duration = START + STEP * N_STEPS
    ticks = []
    for k in range(int(round(duration / DT)) + 1):
        t = round(k * DT, 6)
        loaded, soles = list(FEET), {}
        j = int(np.searchsorted(touchdowns, t + 1e-9, side="right")) - 1
        if 0 <= j < N_STEPS:
            swing = FEET[j % 2]
            lift_off = round(touchdowns[j] + ds * STEP, 6)
            if t >= lift_off - 1e-9:
                loaded.remove(swing)
                u = (t - lift_off) / (touchdowns[j + 1] - lift_off)
                x, y, _ = home_sole(robot, swing)
                soles[swing] = (x, y, _q(lift * math.sin(math.pi * u)))
        sway = 0.5 * bounce * math.sin(math.pi * (t - START) / STEP) if t >= START else 0.0
        qpos = poser((0.0, _q(sway), 0.0), **soles)
        for foot, (motor, spring) in knees.items():
            link = qpos[motor] + qpos[spring]
            deflection = knee(t) if callable(knee) else knee
            qpos[spring] = deflection if loaded == [foot] else 0.0
            qpos[motor] = link - qpos[spring]
        events = []
        if t >= START - 1e-9 and abs((t - START) / STEP - round((t - START) / STEP)) < 1e-6:
            events = [{"kind": "phase", "step": int(round((t - START) / STEP))}]
        ticks.append(Tick(t, qpos=qpos, pairs=standing_pairs(robot, loaded=loaded), events=events))
    spec = make_spec(robot, duration, controller={"type": "timeprojection", "params": params or {}})
    return write_log(path, ticks, spec, outcome)


@pytest.fixture(scope="module")
def paper_gait(tmp_path_factory: pytest.TempPathFactory) -> LogData:
    """The paper's gait: 20 % double support, 2.4 cm lift, 2.2 cm bounce, on time."""
    return _gait_log(tmp_path_factory.mktemp("gait") / "paper.mcap")


# ---- load, swings ---------------------------------------------------------------------------


def test_loaded_mask_has_hysteresis() -> None:
    """A foot is loaded above 10 % of the weight and unloaded below 5 %, unchanged between."""
    fz = np.array([100.0, 8.0, 4.0, 8.0, 12.0, 6.0, 4.0])
    assert loaded_mask(fz, 100.0).tolist() == [True, True, False, False, True, True, False]


def test_short_unloading_is_no_swing() -> None:
    """An unloaded interval shorter than 50 ms (a landing's chatter) is not a swing."""
    t = np.arange(0.0, 1.0, 0.01)
    loaded = np.ones(t.size, dtype=bool)
    loaded[10:13] = False  # 30 ms
    loaded[40:70] = False  # 300 ms
    assert foot_swings(t, loaded, "left_foot") == [("left_foot", 40, 70)]


# ---- double support (3LP Model: "approximately 20% in each phase") ---------------------------


def test_double_support_of_the_paper(paper_gait: LogData) -> None:
    """Both feet loaded for 80 ms of every 0.4 s step: 20 % double support."""
    assert measured(paper_gait, "double_support_fraction") == pytest.approx(0.2, abs=1e-6)
    assert measured(paper_gait, "double_support_fraction:0.5-2.9") == pytest.approx(0.2, abs=1e-6)


def test_short_double_support_misses_the_paper(tmp_path: Path) -> None:
    """Both feet loaded for 20 ms of a step: 5 %, outside a band around 20 %."""
    d = _gait_log(tmp_path / "ds.mcap", ds=0.05)
    assert measured(d, "double_support_fraction") == pytest.approx(0.05, abs=1e-6)


def test_double_support_fraction_of_each_step() -> None:
    """Steps between touchdowns: the time both feet are loaded over each step's length."""
    t = np.round(np.arange(0.0, 1.0, 0.01), 6)
    left = (t < 0.3) | (t >= 0.6)
    right = t >= 0.2
    out = double_support_fractions(t, {"l": left, "r": right}, np.array([0.2, 0.6, 0.9]))
    assert out == pytest.approx([0.1 / 0.4, 1.0])


def test_double_support_needs_two_steps(tmp_path: Path) -> None:
    """A log of standing only has no step to measure the double support of."""
    ticks = [Tick(round(k * DT, 6)) for k in range(50)]
    d = write_log(tmp_path / "stand.mcap", ticks, make_spec(ROBOT, 0.5))
    assert "0 step(s) between touchdowns" in unmeasurable_reason(d, "double_support_fraction")


# ---- swing lift (Fig. 8: "about 2.4cm") -----------------------------------------------------


def test_swing_lift_of_the_paper(paper_gait: LogData) -> None:
    """A sole centre lifted 2.4 cm on a half sine measures a 2.4 cm lift."""
    assert measured(paper_gait, "swing_lift") == pytest.approx(0.024, abs=5e-4)


def test_low_swing_misses_the_paper(tmp_path: Path) -> None:
    """A foot unloaded but lifted 5 mm measures 5 mm (Fig. 6: the lift not realised)."""
    d = _gait_log(tmp_path / "low.mcap", lift=0.005)
    assert measured(d, "swing_lift") == pytest.approx(0.005, abs=5e-4)


def test_swing_lift_window_past_a_fall_not_measurable(tmp_path: Path) -> None:
    """A window the run did not reach (it fell) has no lift to report."""
    d = _gait_log(tmp_path / "fell.mcap", outcome="fell")
    assert "before the end of the window" in unmeasurable_reason(d, "swing_lift:1-5")


# ---- lateral bounce (Lateral Plane: "2.2 cm total displacement of the pelvis") ---------------


def test_lateral_bounce_is_peak_to_peak(paper_gait: LogData) -> None:
    """A pelvis swaying ±1.1 cm over a stride bounces 2.2 cm peak to peak."""
    assert measured(paper_gait, "lateral_bounce") == pytest.approx(0.022, abs=5e-4)


def test_large_lateral_bounce(tmp_path: Path) -> None:
    """A pelvis swaying ±3 cm bounces 6 cm, far from 2.2 cm."""
    assert measured(_gait_log(tmp_path / "b.mcap", bounce=0.06), "lateral_bounce") == (
        pytest.approx(0.06, abs=5e-4)
    )


def test_lateral_bounce_is_normal_to_the_heading() -> None:
    """A pelvis walking along y with a heading of 90° sways along x: that is the bounce."""
    t = np.linspace(0.0, 0.8, 81)
    xy = np.stack([0.01 * np.sin(np.pi * t / 0.4), 0.2 * t], axis=1)
    yaw = np.full(t.size, math.pi / 2)
    assert lateral_excursions(t, xy, yaw, np.array([0.0, 0.8])) == pytest.approx([0.02], abs=1e-4)


# ---- knee spring compressions (Fig. 7) ------------------------------------------------------


def test_knee_compression_in_single_support(paper_gait: LogData) -> None:
    """Knee springs deflected 0.05 rad while their foot carries the weight measure 0.05."""
    assert measured(paper_gait, "knee_spring_compression:left") == pytest.approx(0.05, abs=1e-9)
    assert measured(paper_gait, "knee_spring_compression:right@0.5-2.9") == pytest.approx(
        0.05, abs=1e-9
    )


def test_knee_extended_under_load_is_negative(tmp_path: Path) -> None:
    """A knee whose link opens against its motor under the load reads a negative compression."""
    d = _gait_log(tmp_path / "k.mcap", knee=-0.02)
    assert measured(d, "knee_spring_compression:left") == pytest.approx(-0.02, abs=1e-9)


def test_compression_signed_by_the_bend() -> None:
    """A knee bent the negative way compresses when its deflection is negative."""
    assert spring_compression(np.array([-0.03]), np.array([-0.4])) == pytest.approx([0.03])
    assert spring_compression(np.array([-0.03]), np.array([0.4])) == pytest.approx([-0.03])


def test_rigid_knee_has_no_spring(tmp_path: Path) -> None:
    """dyros_red's knees have no series spring: nothing to measure."""
    ticks = [Tick(round(k * DT, 6)) for k in range(20)]
    d = write_log(tmp_path / "rigid.mcap", ticks, make_spec("dyros_red", 0.2))
    reason = unmeasurable_reason(d, "knee_spring_compression:left")
    assert "no series-elastic left knee" in reason


def test_knee_compression_mean_is_the_papers_average(tmp_path: Path) -> None:
    """Fig. 7's "statistical average": the mean over the full-load samples, 0.05 rad when
    every such sample is 0.05, and the mean (not the median) when they spread."""
    d = _gait_log(tmp_path / "k.mcap", knee=0.05)
    assert measured(d, "knee_spring_compression_mean:left") == pytest.approx(0.05, abs=1e-9)
    assert measured(d, "knee_spring_compression_mean:right@0.5-2.9") == pytest.approx(
        0.05, abs=1e-9
    )
    spread = _gait_log(tmp_path / "s.mcap", knee=lambda t: 0.08 if t < 1.0 else 0.02)
    samples = full_load_knee_compressions(spread, "left")
    assert float(np.mean(samples)) != pytest.approx(float(np.median(samples)), abs=1e-3)
    assert measured(spread, "knee_spring_compression_mean:left") == pytest.approx(
        float(np.mean(samples)), abs=1e-12
    )


def test_knee_deflection_ratio_is_one_when_mu_is_the_measured_average(tmp_path: Path) -> None:
    """A run whose μ (per knee) is its measured mean compression reads 1 on each knee (Eq. 21
    identified by Fig. 7's procedure)."""
    d = _gait_log(tmp_path / "mu.mcap", knee=0.05, params={"knee_deflection": [0.05, 0.05]})
    assert measured(d, "knee_deflection_ratio:left") == pytest.approx(1.0, abs=1e-9)
    assert measured(d, "knee_deflection_ratio:right") == pytest.approx(1.0, abs=1e-9)


def test_knee_deflection_ratio_misses_a_mu_not_identified(tmp_path: Path) -> None:
    """A μ of 0.1 rad on knees that compress 0.05 rad reads 0.5, outside a ±10 % band; the
    right knee's own μ is used for the right knee."""
    d = _gait_log(tmp_path / "mu.mcap", knee=0.05, params={"knee_deflection": [0.1, 0.025]})
    assert measured(d, "knee_deflection_ratio:left") == pytest.approx(0.5, abs=1e-9)
    assert measured(d, "knee_deflection_ratio:right") == pytest.approx(2.0, abs=1e-9)


def test_knee_deflection_ratio_needs_a_set_mu(paper_gait: LogData) -> None:
    """A controller that derives μ from the home posture has no set μ to compare with."""
    assert "derived from the home posture" in unmeasurable_reason(
        paper_gait, "knee_deflection_ratio:left"
    )


def test_knee_compression_names_a_side() -> None:
    """The argument is a side, optionally with a window; anything else is a spec error."""
    check_metric_arg("knee_spring_compression:right@2-10")
    with pytest.raises(MetricArgError, match="neither left nor right"):
        check_metric_arg("knee_spring_compression:knee")


# ---- touchdowns against the fixed timing (Fig. 19) ------------------------------------------


def test_touchdowns_on_time(paper_gait: LogData) -> None:
    """Feet that land at the phase changes lead them by 0."""
    assert measured(paper_gait, "touchdown_lead") == pytest.approx(0.0, abs=1e-9)
    assert measured(paper_gait, "max_touchdown_lead") == pytest.approx(0.0, abs=1e-9)


def test_touchdowns_earlier_than_expected(tmp_path: Path) -> None:
    """Feet landing 20 ms before every phase change lead it by 20 ms (Fig. 19's claim holds)."""
    d = _gait_log(tmp_path / "early.mcap", lead=lambda j: 0.02)
    assert measured(d, "touchdown_lead") == pytest.approx(0.02, abs=1e-9)


def test_touchdowns_later_than_expected(tmp_path: Path) -> None:
    """Feet landing 30 ms after the phase changes have a negative lead (the claim fails)."""
    d = _gait_log(tmp_path / "late.mcap", lead=lambda j: -0.03)
    assert measured(d, "touchdown_lead") == pytest.approx(-0.03, abs=1e-9)


def test_one_early_landing_after_a_push(tmp_path: Path) -> None:
    """One step landing 100 ms early among punctual ones: the largest lead is 100 ms, in the
    window after it the mean is 0."""
    d = _gait_log(tmp_path / "push.mcap", lead=lambda j: 0.1 if j == 3 else 0.0)
    assert measured(d, "max_touchdown_lead") == pytest.approx(0.1, abs=1e-9)
    assert measured(d, "max_touchdown_lead:1.9-2.2") == pytest.approx(0.1, abs=1e-9)
    assert measured(d, "touchdown_lead:2.2-2.9") == pytest.approx(0.0, abs=1e-9)


def test_touchdown_lead_belongs_to_the_phase_after_the_swing_midpoint() -> None:
    """A swing from 0.55 to 0.85 s belongs to the 0.9 s phase change; after the last, none."""
    leads = touchdown_leads(np.array([0.5, 0.9, 1.3]), [(0.55, 0.85), (0.98, 1.32), (1.4, 1.6)])
    assert leads == pytest.approx([0.05, -0.02])


def test_touchdown_lead_needs_the_gait_clock(tmp_path: Path) -> None:
    """Without phase changes there is no expected touchdown."""
    ticks = [Tick(round(k * DT, 6)) for k in range(20)]
    d = write_log(tmp_path / "clock.mcap", ticks, make_spec(ROBOT, 0.2))
    assert "0 phase change(s) logged" in unmeasurable_reason(d, "touchdown_lead")


# ---- touchdown irregularity without dead-zones (Fig. 15) -------------------------------------


def test_regular_touchdowns_have_no_spread(paper_gait: LogData) -> None:
    """Feet that all land on the phase changes have a touchdown spread of 0 (Fig. 15 fails)."""
    assert measured(paper_gait, "touchdown_lead_spread") == pytest.approx(0.0, abs=1e-9)


def test_early_and_late_touchdowns_spread(tmp_path: Path) -> None:
    """Feet landing 40 ms early and 40 ms late in turn spread by 40 ms (Fig. 15 holds)."""
    d = _gait_log(tmp_path / "irregular.mcap", lead=lambda j: 0.04 if j % 2 else -0.04)
    assert measured(d, "touchdown_lead_spread") == pytest.approx(0.04, abs=2e-3)
