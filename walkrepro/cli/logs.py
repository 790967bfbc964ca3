"""The commands on one run's log: ``plot`` (the paper's figures), ``verify`` (re-simulate
and compare), ``render`` (a snapshot strip or a video) and ``export`` (a Rerun recording)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.markup import escape

from walkrepro.cli.common import ForceOption, PartialOption, friendly_errors, make_console
from walkrepro.errors import WalkreproError
from walkrepro.runs import results


@friendly_errors
def plot(
    runs: Annotated[
        list[Path],
        typer.Argument(help="Run directory or log (two to compare runs), or a sweep directory."),
    ],
    out: Annotated[
        Path | None,
        typer.Option(
            help="Figure directory (default: RUN/figures): new, empty, or one walkrepro "
            "wrote; any other is refused unless --force."
        ),
    ] = None,
    force: ForceOption = False,
    partial: PartialOption = False,
) -> None:
    """Redraw the paper's figures from one run, or compare two runs, or a sweep's maps."""
    from walkrepro.present.figures import plot_compare, plot_run
    from walkrepro.runtime import outdir
    from walkrepro.studies.sweep.store import is_sweep_dir

    if out is not None:
        outdir.claim_root(out, outdir.FIGURES, force)

    if len(runs) == 1 and is_sweep_dir(runs[0]):
        from walkrepro.studies.sweep.maps import plot_sweep

        for path in plot_sweep(runs[0], out):
            make_console().print(f"wrote {path}")
        return
    if len(runs) > 2:
        raise WalkreproError("plot takes one run, or two runs to compare.")
    resolved = [results.resolve_run(r) for r in runs]
    if len(resolved) == 1:
        directory, log = resolved[0]
        written = plot_run(log, out or directory / results.FIGURES_DIR, partial)
    else:
        written = plot_compare(
            resolved[0][1], resolved[1][1], out or resolved[0][0] / results.FIGURES_DIR, partial
        )
    for path in written:
        make_console().print(f"wrote {path}")


@friendly_errors
def verify(
    log: Annotated[Path, typer.Argument(help="A log.mcap (or its run directory).")],
    tolerance: Annotated[float, typer.Option(help="Largest allowed deviation.")] = 1e-9,
) -> None:
    """Re-simulate a log from its scene, initial state and inputs; compare with its states.

    Exit 1 when the replay deviates beyond the tolerance, or when the log is truncated or
    damaged (what could be read is still replayed and reported).
    """
    from walkrepro.sim.replay import verify_log

    directory, log_path = results.resolve_run(log)
    if not log_path.is_file():
        raise WalkreproError(
            f"{directory}: this run has no {results.LOG_FILE} (it stopped before its log was "
            f"opened; see its {results.RUN_FILE}); there is nothing to verify."
        )
    report = verify_log(log_path, tolerance)
    logged = "?" if report.n_logged is None else str(report.n_logged)
    replayed = f"replayed {report.n_steps} of {logged} logged steps"
    compared = f"compared {report.n_states_compared} states"
    if report.n_states_compared:
        compared += (
            f"; largest deviation {report.max_deviation:.3g} (step {report.worst_step}, "
            f"{report.worst_field}); tolerance {report.tolerance:g}"
        )
    if report.damage:
        upto = f" (up to t = {report.last_time:.4g} s)" if report.n_states_read else ""
        unknown = ""
        if report.n_logged is None:
            lost = "cut off" if report.damage.startswith("truncated") else "damaged"
            unknown = f" (? = unknown: the summary that counts them is {lost})"
        make_console().print(
            f"[red]DAMAGED[/]: {escape(str(log_path))} is {escape(report.damage)}. Read "
            f"{report.n_states_read} states{upto} and the inputs of {report.n_steps} steps; "
            f"{replayed}{unknown}; {compared}.",
            highlight=False,
        )
        raise typer.Exit(code=1)
    status = "[green]OK[/]" if report.ok else "[red]FAILED[/]"
    make_console().print(f"{status}: {replayed}, {compared}", highlight=False)
    if not report.ok:
        raise typer.Exit(code=1)


@friendly_errors
def render(
    run_path: Annotated[Path, typer.Argument(help="Run directory or log.")],
    video: Annotated[
        bool,
        typer.Option(
            "--video",
            help="Write an MP4 (H.264) of the whole run at real time instead of a strip.",
        ),
    ] = False,
    at: Annotated[str, typer.Option(help="Comma-separated times [s] (strip).")] = "0,1,2,3,4",
    out: Annotated[
        Path | None,
        typer.Option(
            help="Output path (default: RUN/figures/snapshots.png, or RUN/video.mp4 with --video)."
        ),
    ] = None,
    width: Annotated[
        int | None,
        typer.Option(min=2, help="Frame width [px] (default: 480 strip, 640 video)."),
    ] = None,
    height: Annotated[
        int | None,
        typer.Option(min=2, help="Frame height [px] (default: 640 strip, 360 video)."),
    ] = None,
    fps: Annotated[int, typer.Option(min=1, help="Video frames per simulated second.")] = 30,
    contact_forces: Annotated[
        bool, typer.Option("--contact-forces", help="Draw contact forces in the video.")
    ] = False,
    force: Annotated[
        bool, typer.Option("--force", help="Replace the --out file if it exists.")
    ] = False,
    partial: PartialOption = False,
) -> None:
    """Render a snapshot strip of a run, or with --video an MP4 of it, headless.

    The video follows the pelvis from the side, colours each link, draws disturbance forces
    as red arrows and overlays the time and the controller's state.
    """
    from walkrepro.runtime import outdir

    directory, log = results.resolve_run(run_path)
    if video:
        from walkrepro.present.video import DEFAULT_HEIGHT, DEFAULT_WIDTH, VIDEO_FILE, render_video

        target = outdir.check_file(out or directory / VIDEO_FILE, force, ours=out is None)
        info = render_video(
            log,
            target,
            fps=fps,
            width=width or DEFAULT_WIDTH,
            height=height or DEFAULT_HEIGHT,
            contact_forces=contact_forces,
            partial=partial,
        )
        make_console().print(
            f"wrote {info.path} ({info.n_frames} frames, {info.duration:.2f} s at {info.fps} fps)"
        )
        return
    from walkrepro.present.render import render_strip

    try:
        times = [float(x) for x in at.split(",") if x.strip()]
    except ValueError:
        raise WalkreproError(
            f"--at {at!r}: expected comma-separated times in seconds, e.g. 0,2,4."
        ) from None
    target = out or directory / results.FIGURES_DIR / "snapshots.png"
    target = outdir.check_file(target, force, ours=out is None)
    path = render_strip(log, times, target, width or 480, height or 640, partial)
    make_console().print(f"wrote {path}")


@friendly_errors
def export(
    run_path: Annotated[Path, typer.Argument(help="Run directory or log.")],
    rerun: Annotated[
        bool,
        typer.Option(
            "--rerun",
            help="A Rerun recording (.rrd): the robot, contact and disturbance arrows, the "
            'paper\'s plots, on simulated time. Needs pip install "walkrepro\\[rerun]".',
        ),
    ] = False,
    out: Annotated[
        Path | None,
        typer.Option(help="Output file (default: the log's name with .rrd: RUN/log.rrd)."),
    ] = None,
    force: Annotated[
        bool, typer.Option("--force", help="Replace the output file if it exists.")
    ] = False,
    partial: PartialOption = False,
) -> None:
    """Export a run's log for another viewer, from the log alone (no re-simulation).

    With --rerun, writes a recording that opens in Rerun (`rerun RUN/log.rrd`) on a 3D view
    of the robot and the plots of its controller; the run's verdict comes along if the run
    directory has one.
    """
    if not rerun:
        raise WalkreproError("export: choose a format: --rerun (the only one so far).")
    from walkrepro.present.rerun_export import export_rerun, import_rerun

    import_rerun()  # the missing SDK is the first thing to say
    directory, log = results.resolve_run(run_path)
    if not log.is_file():
        raise WalkreproError(
            f"{directory}: this run has no {results.LOG_FILE} (see its {results.RUN_FILE}); "
            "there is nothing to export."
        )
    check = directory / results.CHECK_FILE  # the verdict of a run directory's log
    verdict = check if log.name == results.LOG_FILE and check.is_file() else None
    from walkrepro.runtime import outdir

    target = outdir.check_file(out or log.with_suffix(".rrd"), force)
    done = export_rerun(log, target, verdict, force, partial)
    for note in done.skipped:
        make_console(stderr=True).print(f"[yellow]skipped:[/] {escape(note)}", highlight=False)
    size = done.path.stat().st_size / 1e6
    make_console().print(
        f"wrote {done.path} ({size:.1f} MB: {done.n_poses} poses over {done.duration:.2f} s, "
        f"{len(done.plots)} plots, in {done.seconds:.1f} s); open it with: rerun {done.path}",
        highlight=False,
    )
