"""Benchmark bookkeeping (structure and consistency, never wall-clock thresholds)."""

from __future__ import annotations

import pytest

from walkrepro.runs.resolve import resolve_spec
from walkrepro.specs.files import load_spec
from walkrepro.studies.bench import bench_experiment, machine_info


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


@pytest.mark.slow
def test_bench_json_keeps_the_earlier_results_it_compares_with(tmp_path) -> None:  # noqa: ANN001
    """`bench --compare OLD --json NEW` shows both factors and keeps OLD under `before`."""
    import json

    from typer.testing import CliRunner

    from walkrepro.cli import app

    old = tmp_path / "old.json"
    old.write_text(json.dumps({"machine": {}, "results": [
        {"experiment": "stand_coman", "real_time_factor": 0.123}]}))  # fmt: skip
    new = tmp_path / "new.json"
    args = ["bench", "stand_coman", "--set", "sim.duration=0.1", "--compare", str(old)]
    result = CliRunner().invoke(app, [*args, "--json", str(new)])
    assert result.exit_code == 0, result.output
    assert "RTF before" in result.output and "0.12" in result.output
    payload = json.loads(new.read_text())
    assert payload["before"]["results"][0]["real_time_factor"] == 0.123
    (row,) = payload["results"]
    assert 0 < row["logging_share"] < 1 and row["memory_growth"] == row["memory_growth"]


def test_bench_compare_with_a_wrong_file_is_a_clear_error(tmp_path) -> None:  # noqa: ANN001
    from typer.testing import CliRunner

    from walkrepro.cli import app

    bad = tmp_path / "bad.json"
    bad.write_text("{}")
    result = CliRunner().invoke(app, ["bench", "stand_coman", "--compare", str(bad)])
    assert result.exit_code == 2
    assert "not a `walkrepro bench --json` file" in result.output
    assert "Traceback" not in result.output


def test_repeat_keeps_the_fastest_run_and_floor(monkeypatch: pytest.MonkeyPatch) -> None:
    """With --repeat N the fastest run and the fastest floor are reported (no clock read)."""
    from walkrepro.runs.runner import RunResult, RunTiming
    from walkrepro.studies import bench

    walls, floors = iter([3.0, 1.0, 2.0]), iter([0.5, 0.7, 0.4])

    def fake_run(spec, log_path):  # noqa: ANN001, ANN202
        timing = RunTiming(stages={"logging": 0.1}, tick_median=1e-4, tick_p99=2e-4, n_ticks=100)
        return RunResult(spec.name, log_path, "complete", 0.2, next(walls), None, "", timing)

    monkeypatch.setattr(bench, "run", fake_run)
    monkeypatch.setattr(bench, "floor_time", lambda log_path: next(floors))
    spec = resolve_spec(load_spec("stand_coman", ["sim.duration=0.2"])).spec
    r = bench.bench_experiment(spec, repeat=3)
    assert r.wall_time == 1.0 and r.floor_wall_time == 0.4
    assert r.floor_ratio == pytest.approx(2.5) and r.real_time_factor == pytest.approx(0.2)


def test_repeats_go_round_the_experiments(monkeypatch: pytest.MonkeyPatch) -> None:
    """--repeat runs A, B, A, B (not A, A, B, B), so a slow spell of the host does not meet
    every run of one experiment; each experiment keeps its own fastest run and floor."""
    from walkrepro.runs.runner import RunResult, RunTiming
    from walkrepro.studies import bench

    order: list[str] = []
    walls = iter([2.0, 5.0, 1.0, 6.0])  # A, B, A, B

    def fake_run(spec, log_path):  # noqa: ANN001, ANN202
        order.append(spec.name)
        timing = RunTiming(stages={"logging": 0.1}, tick_median=1e-4, tick_p99=2e-4, n_ticks=100)
        return RunResult(spec.name, log_path, "complete", 0.2, next(walls), None, "", timing)

    monkeypatch.setattr(bench, "run", fake_run)
    monkeypatch.setattr(bench, "floor_time", lambda log_path: 0.5)
    specs = [
        resolve_spec(load_spec(name, ["sim.duration=0.2"])).spec
        for name in ("stand_coman", "stand_dyros_red")
    ]
    started: list[tuple[str, int]] = []
    a, b = bench.bench_experiments(specs, 2, on_start=lambda s, r: started.append((s.name, r)))
    assert order == ["stand_coman", "stand_dyros_red"] * 2
    assert started == [("stand_coman", 0), ("stand_dyros_red", 0), ("stand_coman", 1),
                       ("stand_dyros_red", 1)]  # fmt: skip
    assert (a.experiment, a.wall_time) == ("stand_coman", 1.0)
    assert (b.experiment, b.wall_time) == ("stand_dyros_red", 5.0)
