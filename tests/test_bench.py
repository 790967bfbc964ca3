"""Benchmark bookkeeping (structure and consistency, never wall-clock thresholds)."""

from __future__ import annotations

import pytest

from walkrepro.bench import bench_experiment, machine_info
from walkrepro.spec import load_spec, resolve_spec


@pytest.mark.slow
def test_bench_reports_every_stage_and_the_floor() -> None:
    """A benchmark reports each runner stage, a consistent real-time factor and a positive floor."""
    spec = resolve_spec(load_spec("stand_coman", ["sim.duration=0.2"])).spec
    r = bench_experiment(spec)
    assert r.outcome == "complete"
    assert set(r.per_tick) >= {"physics", "sensors", "controller", "logging", "bookkeeping"}
    assert r.real_time_factor == pytest.approx(r.sim_time / r.wall_time)
    assert r.floor_wall_time > 0 and r.floor_ratio == pytest.approx(r.wall_time / r.floor_wall_time)
    assert r.tick_median <= r.tick_p99
    assert r.control_rate == pytest.approx(500.0)
    # The stage totals account for the loop's time (what is not timed is small).
    n_ticks = round(r.sim_time * r.control_rate)
    accounted = sum(v for k, v in r.per_tick.items() if "." not in k) * n_ticks
    assert accounted == pytest.approx(r.wall_time, rel=0.2)


def test_machine_info_names_cores_and_cpu() -> None:
    """The machine description carries the core count and CPU model."""
    info = machine_info()
    assert int(info["cores"]) >= 1 and info["cpu"]
