"""A run's log as a Rerun recording (``.rrd``) that opens on a useful view:
``walkrepro export RUN --rerun``.

Rerun opens an MCAP file itself, but a walkrepro log then shows an empty viewport (see
``docs/log-contract.md``). The export reads the log alone (its ``scene.xml`` and
``spec.yaml`` attachments, its topics) and writes, on the timeline ``sim_time`` (the
simulated time):

- ``world``: the scene, z up. ``world/ground``: the world body's geoms (the floor, fixed
  obstacles); ``world/bodies/<body>``: each body's pose (MuJoCo's kinematics of the logged
  ``qpos``, every :data:`POSE_PERIOD`) holding its geoms (:func:`walkrepro.log.foxglove.geom_shape`)
  as boxes, ellipsoids, cylinders and capsules;
- ``world/forces/contact/<foot>``: each foot's net contact force as an arrow at its centre of
  pressure; ``world/forces/disturbance/<body>``: an applied disturbance while it acts, an
  arrow ending at the body's centre of mass. Arrows are :data:`FORCE_SCALE` m per newton;
- ``plots/run/<plot>/<line>``: every run's feet's normal forces, pelvis height and
  disturbance magnitudes; ``plots/<controller>/<plot>/<line>``: the controller's declared
  plots (:mod:`walkrepro.present.plots`, ``Plugin.plots``), at every logged tick, each line named
  with its unit;
- ``events``: the ``/events`` as text; ``verdict``: the run's ``check.json`` as a table;
- a default blueprint: the 3D view following the pelvis, the plots, the verdict.

Per-tick data go out as columns (``send_columns``), one call per entity.
"""

from __future__ import annotations

import json
import math
import re
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple

import mujoco
import numpy as np

from walkrepro import plugins
from walkrepro.errors import WalkreproError
from walkrepro.evaluation.metrics import FOOT_BODIES
from walkrepro.log import record
from walkrepro.log.foxglove import GeomShape, body_names, geom_shape
from walkrepro.present.plots import Plot, Series, read_series, signal_plots
from walkrepro.runtime import outdir
from walkrepro.specs.models import spec_from_yaml_text

#: The timeline: simulated time.
TIMELINE = "sim_time"
#: Simulated time between two poses of the robot [s]: 60 Hz, smooth playback.
POSE_PERIOD = 1 / 60
#: Arrow length per newton of force [m/N]: 1 kN draws 1 m.
FORCE_SCALE = 1e-3
#: Smallest normal force that draws a foot's contact arrow [N]; below, the foot is in the air
#: and its centre of pressure is not defined.
MIN_CONTACT_FORCE = 1.0
#: The oldest Rerun SDK whose API the export uses (the ``rerun`` extra's lower bound).
MIN_RERUN = (0, 41)
#: What installs the Rerun SDK with walkrepro.
INSTALL = 'pip install "walkrepro[rerun]"'
#: The body a view follows, when the scene has it.
TRACKED_BODY = "pelvis"
#: Group of the plots every run has (``plots/run/...``); a controller's are under its type.
RUN_GROUP = "run"
#: Where the 3D view's eye starts [m], and what it looks at, in the world.
EYE_POSITION, EYE_TARGET = (1.0, -1.9, 1.1), (0.0, 0.0, 0.6)
#: Opacity of the bodies that move (the robot), so that the force arrows inside show.
MOVING_ALPHA = 0.55
#: Arrow and line colours (RGB): each foot's contact force (left, right), disturbances.
FOOT_COLOURS = ((40, 120, 230), (20, 170, 80))
DISTURBANCE_COLOUR = (230, 40, 40)


def import_rerun() -> Any:
    """The ``rerun`` module.

    Raises:
        WalkreproError: the Rerun SDK is not installed, or older than :data:`MIN_RERUN`;
            the message names the install.
    """
    try:
        import rerun
    except ImportError:
        raise WalkreproError(
            f"walkrepro export --rerun needs the Rerun SDK, which is not installed: {INSTALL}"
        ) from None
    version = tuple(int(x) for x in re.findall(r"\d+", rerun.__version__)[:2])
    if version < MIN_RERUN:
        raise WalkreproError(
            f"walkrepro export --rerun needs Rerun SDK {'.'.join(map(str, MIN_RERUN))} or "
            f"newer, and {rerun.__version__} is installed: {INSTALL} --upgrade"
        )
    return rerun


@dataclass(frozen=True)
class RerunExport:
    """What :func:`export_rerun` wrote.

    Attributes:
        path: the ``.rrd`` file.
        n_poses: poses of the robot written.
        duration: simulated time covered [s].
        plots: the plots' names, with their units, in the blueprint's order.
        seconds: wall time of the export [s].
        skipped: why each declared line the log does not have was left out (a log older
            than the controller's declarations).
    """

    path: Path
    n_poses: int
    duration: float
    plots: tuple[str, ...]
    seconds: float
    skipped: tuple[str, ...] = ()


def export_rerun(
    log_path: Path, out: Path, check_file: Path | None, force: bool, partial: bool = False
) -> RerunExport:
    """Writes the Rerun recording of the log at ``log_path`` to ``out`` (see the module
    docstring).

    The file is written under a temporary name next to ``out`` and renamed when complete,
    so ``out`` is never a partial recording.

    Args:
        log_path: the run's ``log.mcap``.
        out: the ``.rrd`` to write.
        check_file: the run's ``check.json``, shown as the verdict (None: no verdict).
        force: replace ``out`` if it exists.
        partial: export a cut or damaged log for what it holds: the recording's name and
            its verdict panel then say ``PARTIAL`` (and the run's earlier verdict is not
            shown as if it held); without it such a log is refused
            (:class:`walkrepro.log.integrity.DamagedLogError`).

    Raises:
        WalkreproError: the Rerun SDK is missing, ``out`` exists and ``force`` is off, or
            the log cannot be read or has no state. A declared line the log does not have
            is left out, and said so in :attr:`RerunExport.skipped`.
    """
    rr = import_rerun()
    start = time.perf_counter()
    from walkrepro.log.integrity import read_checked_log

    log, found = read_checked_log(log_path, partial)
    states = log.arrays(record.TOPIC_STATE)
    if not states:
        raise WalkreproError(f"{log_path}: no {record.TOPIC_STATE} messages; nothing to show.")
    model = mujoco.MjModel.from_xml_string(log.scene_xml)
    spec = spec_from_yaml_text(log.spec_yaml, f"{log_path}:spec.yaml")
    poses = _poses(model, states["t"], states["qpos"])
    contacts = _foot_wrenches(log)
    pushes = _disturbances(log, spec.sim.timestep)
    plots = [(RUN_GROUP, p) for p in _run_plots(model, pushes)]
    plots += [(spec.controller.type, p) for p in _controller_plots(log, spec.controller.type)]

    outdir.check_file(out, force)  # a directory, an existing file, a read-only place
    rec = rr.RecordingStream("walkrepro", recording_id=f"{spec.name}-{log_path.parent.name}")
    with outdir.writing_file(out) as temporary:
        panel = check_file is not None or not found.whole
        rec.save(temporary, default_blueprint=_blueprint(model, plots, panel))
        rec.send_recording_name(f"{spec.name} ({found.short()})" if not found.whole else spec.name)
        origin = log.metadata.get("log_time_origin")
        if origin is not None:
            rec.send_recording_start_time_nanos(int(origin))
        _send_scene(rr, rec, model, poses)
        _send_contact_arrows(rr, rec, contacts, model, poses)
        _send_disturbance_arrows(rr, rec, pushes, model, poses)
        skipped = _send_plots(rr, rec, log, plots, _derived_series(contacts, pushes))
        _send_events(rr, rec, log)
        if not found.whole:  # the verdict of the whole run is not this log's
            text = f"# {spec.name}: PARTIAL\n\n{found.describe()}.\n"
            rec.log("verdict", rr.TextDocument(text, media_type="text/markdown"), static=True)
        elif check_file is not None:
            verdict = rr.TextDocument(_verdict_text(check_file), media_type="text/markdown")
            rec.log("verdict", verdict, static=True)
        rec.flush()
        rec.disconnect()
    return RerunExport(
        out,
        len(poses.t),
        float(poses.t[-1] - poses.t[0]),
        tuple(p.name for _, p in plots),
        time.perf_counter() - start,
        tuple(skipped),
    )


@dataclass(frozen=True)
class _Poses:
    """The scene's kinematics at the pose times.

    Attributes:
        t: times [s], shape (N,).
        xpos: body positions in the world [m], shape (N, nbody, 3).
        xquat: body orientations (w, x, y, z), shape (N, nbody, 4).
        xipos: body centres of mass in the world [m], shape (N, nbody, 3).
        site_xpos: site positions in the world [m], shape (N, nsite, 3).
    """

    t: np.ndarray
    xpos: np.ndarray
    xquat: np.ndarray
    xipos: np.ndarray
    site_xpos: np.ndarray


def _poses(model: mujoco.MjModel, t: np.ndarray, qpos: np.ndarray) -> _Poses:
    """MuJoCo's kinematics of the logged states nearest a grid of :data:`POSE_PERIOD`, and of
    the last state."""
    grid = np.arange(t[0], t[-1], POSE_PERIOD)
    rows = np.unique(np.append(np.minimum(np.searchsorted(t, grid - 1e-9), t.size - 1), t.size - 1))
    data = mujoco.MjData(model)
    n = rows.size
    out = _Poses(
        t[rows].astype(float),
        np.zeros((n, model.nbody, 3)),
        np.zeros((n, model.nbody, 4)),
        np.zeros((n, model.nbody, 3)),
        np.zeros((n, model.nsite, 3)),
    )
    for i, row in enumerate(rows):
        data.qpos[:] = qpos[row]
        mujoco.mj_kinematics(model, data)
        out.xpos[i], out.xquat[i], out.xipos[i] = data.xpos, data.xquat, data.xipos
        out.site_xpos[i] = data.site_xpos
    return out


def entity_part(name: str) -> str:
    """``name`` as one part of an entity path (Rerun's escaping)."""
    return re.sub(r"[^\w\-.]", "_", name)


def body_entity(name: str) -> str:
    """The entity of a body: ``world/bodies/<name>``."""
    return f"world/bodies/{entity_part(name)}"


def plot_entity(group: str, plot: Plot, series: Series | None = None) -> str:
    """The entity of a plot, ``plots/<group>/<key>``, or of one of its lines,
    ``plots/<group>/<key>/<label>``; ``group`` is ``run`` for every run's plots, else the
    controller's type."""
    entity = f"plots/{entity_part(group)}/{entity_part(plot.key)}"
    return entity if series is None else f"{entity}/{entity_part(series.label)}"


def _xyzw(quat_wxyz: np.ndarray) -> np.ndarray:
    return quat_wxyz[..., [1, 2, 3, 0]]


def _send_scene(rr: Any, rec: Any, model: mujoco.MjModel, poses: _Poses) -> None:
    """The world (z up), every body's geoms (static) and pose (per pose time)."""
    rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    names = body_names(model)
    shapes: dict[int, list[GeomShape]] = {}
    for g in range(model.ngeom):
        shape = geom_shape(model, g)
        if shape is not None:
            shapes.setdefault(int(model.geom_bodyid[g]), []).append(shape)
    times = [rr.TimeColumn(TIMELINE, duration=poses.t)]
    for body in range(model.nbody):
        entity = "world/ground" if body == 0 else body_entity(names[body])
        alpha = MOVING_ALPHA if model.body_rootid[body] != 0 else 1.0
        for kind, archetype in _archetypes(rr, shapes.get(body, []), alpha).items():
            rec.log(f"{entity}/{kind}", archetype, static=True)
        if body:
            rec.send_columns(
                entity,
                indexes=times,
                columns=rr.Transform3D.columns(
                    translation=poses.xpos[:, body], quaternion=_xyzw(poses.xquat[:, body])
                ),
            )


def _archetypes(rr: Any, shapes: list[GeomShape], alpha: float) -> dict[str, Any]:
    """A body's geoms as one Rerun archetype per kind, in the body's frame, their opacity
    scaled by ``alpha``."""
    out: dict[str, Any] = {}
    for kind in ("box", "ellipsoid", "cylinder", "capsule"):
        group = [s for s in shapes if s.kind == kind]
        if not group:
            continue
        size = np.array([s.size for s in group])
        quats = _xyzw(np.array([s.quat for s in group]))
        centres = np.array([s.pos for s in group])
        colours = np.array([s.rgba for s in group], dtype=np.float32) * [1, 1, 1, alpha]
        if kind == "box":
            out["boxes"] = rr.Boxes3D(
                half_sizes=size / 2, centers=centres, quaternions=quats, colors=colours,
                fill_mode="solid",
            )  # fmt: skip
        elif kind == "ellipsoid":
            out["ellipsoids"] = rr.Ellipsoids3D(
                half_sizes=size / 2, centers=centres, quaternions=quats, colors=colours,
                fill_mode="solid",
            )  # fmt: skip
        elif kind == "cylinder":
            out["cylinders"] = rr.Cylinders3D(
                lengths=size[:, 2], radii=size[:, 0] / 2, centers=centres, quaternions=quats,
                colors=colours, fill_mode="solid",
            )  # fmt: skip
        else:  # Rerun's capsule runs from its translation along +z: start at one end.
            ends = np.array([_rotate(s.quat, [0.0, 0.0, -s.size[2] / 2]) for s in group])
            out["capsules"] = rr.Capsules3D(
                lengths=size[:, 2], radii=size[:, 0] / 2, translations=centres + ends,
                quaternions=quats, colors=colours, fill_mode="solid",
            )  # fmt: skip
    return out


def _rotate(quat_wxyz: np.ndarray, v: list[float]) -> np.ndarray:
    out = np.zeros(3)
    mujoco.mju_rotVecQuat(out, np.asarray(v, dtype=float), quat_wxyz)
    return out


class _Wrenches(NamedTuple):
    """A topic's wrenches per body, on its own time base.

    Attributes:
        t: times [s], shape (N,).
        wrench: body -> its wrench (force [N], torque [N m]), world frame, shape (N, 6).
    """

    t: np.ndarray
    wrench: dict[str, np.ndarray]


def _foot_wrenches(log: record.Log) -> _Wrenches:
    """Each foot's net contact wrench at every ``/sim/contacts`` message (torque about the
    world origin), summed over the world geoms it touches."""
    contacts = log.messages(record.TOPIC_CONTACTS)
    out = {foot: np.zeros((len(contacts), 6)) for foot in FOOT_BODIES}
    for i, message in enumerate(contacts):
        for pair, wrench in message["pairs"].items():
            body = pair.split("/", 1)[0]
            if body in out:
                out[body][i] += wrench
    return _Wrenches(np.array([m["t"] for m in contacts], dtype=float), out)


def _disturbances(log: record.Log, timestep: float) -> _Wrenches:
    """The external wrench applied to each disturbed body at every physics step
    (``/sim/inputs``, MuJoCo's ``xfrc_applied``: force at the body's centre of mass)."""
    inputs = sorted(log.messages(record.TOPIC_INPUTS), key=lambda m: m["step"])
    bodies = sorted({body for m in inputs for body in m["xfrc"]})
    out = {body: np.zeros((len(inputs), 6)) for body in bodies}
    for i, message in enumerate(inputs):
        for body, wrench in message["xfrc"].items():
            out[body][i] = wrench
    return _Wrenches(np.array([m["step"] for m in inputs], dtype=float) * timestep, out)


def centre_of_pressure(wrench: np.ndarray, height: np.ndarray) -> np.ndarray:
    """The point on the horizontal plane z = ``height`` about which a wrench's torque is
    vertical: its centre of pressure [m].

    With force f and torque τ about the world origin, the point p = (x, y, h) has
    τ − p × f vertical: x = (h f_x − τ_y) / f_z, y = (τ_x + h f_y) / f_z.

    Args:
        wrench: force [N] and torque about the world origin [N m], shape (N, 6).
        height: the plane's height h [m] (a foot's sole), shape (N,).

    Returns:
        Shape (N, 3); not finite where the normal force is zero.
    """
    f, tau = wrench[:, :3], wrench[:, 3:]
    with np.errstate(divide="ignore", invalid="ignore"):
        x = (height * f[:, 0] - tau[:, 1]) / f[:, 2]
        y = (tau[:, 0] + height * f[:, 1]) / f[:, 2]
    return np.column_stack((x, y, height))


def _at(t: np.ndarray, times: np.ndarray) -> np.ndarray:
    """Index of the sample at (or just after, else the last) each of ``times``."""
    return np.minimum(np.searchsorted(t, times - 1e-9), t.size - 1)


def _send_arrows(
    rr: Any, rec: Any, entity: str, t: np.ndarray, arrows: tuple[np.ndarray, np.ndarray]
) -> None:
    """One arrow per time where ``arrows`` (origins, vectors; shape (N, 3) each) is finite,
    none at the others."""
    origins, vectors = arrows
    on = np.isfinite(origins).all(axis=1) & np.isfinite(vectors).all(axis=1)
    columns = rr.Arrows3D.columns(origins=origins[on], vectors=vectors[on])
    rec.send_columns(
        entity,
        indexes=[rr.TimeColumn(TIMELINE, duration=t)],
        columns=columns.partition(on.astype(np.int64)),
    )


def _send_contact_arrows(
    rr: Any, rec: Any, contacts: _Wrenches, model: mujoco.MjModel, poses: _Poses
) -> None:
    """Each foot's contact force as an arrow at its centre of pressure, on the plane of its
    sole (site ``<side>_sole``, else the foot body's origin), at each pose time."""
    if not contacts.t.size:
        return
    rows = _at(contacts.t, poses.t)
    for foot, colour in zip(FOOT_BODIES, FOOT_COLOURS, strict=True):
        body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, foot)
        if body < 0:
            continue
        wrench = contacts.wrench[foot][rows]
        sole = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, f"{foot.split('_')[0]}_sole")
        height = poses.site_xpos[:, sole, 2] if sole >= 0 else poses.xpos[:, body, 2]
        cop = centre_of_pressure(wrench, height)
        cop[wrench[:, 2] < MIN_CONTACT_FORCE] = np.nan  # a foot in the air
        entity = f"world/forces/contact/{foot}"
        rec.log(entity, rr.Arrows3D.from_fields(colors=[colour], radii=[0.012]), static=True)
        _send_arrows(rr, rec, entity, poses.t, (cop, wrench[:, :3] * FORCE_SCALE))


def _send_disturbance_arrows(
    rr: Any, rec: Any, pushes: _Wrenches, model: mujoco.MjModel, poses: _Poses
) -> None:
    """Each applied disturbance, while it acts, as an arrow ending at its body's centre of
    mass, at each pose time."""
    names = body_names(model)
    for body, wrench in pushes.wrench.items():
        if body not in names:
            continue
        force = wrench[_at(pushes.t, poses.t), :3]
        vector = force * FORCE_SCALE
        origin = poses.xipos[:, names.index(body)] - vector
        origin[~np.any(force != 0, axis=1)] = np.nan  # not acting
        entity = f"world/forces/disturbance/{entity_part(body)}"
        style = rr.Arrows3D.from_fields(colors=[DISTURBANCE_COLOUR], radii=[0.015])
        rec.log(entity, style, static=True)
        _send_arrows(rr, rec, entity, poses.t, (origin, vector))


def _run_plots(model: mujoco.MjModel, pushes: _Wrenches) -> tuple[Plot, ...]:
    """The plots of every run: each foot's normal contact force, the pelvis height, and the
    magnitude of each disturbance (when the run has one)."""
    out = [
        Plot(
            "contact_force",
            "foot normal contact force",
            "N",
            tuple(Series(f"{record.TOPIC_CONTACTS}.{foot}", foot) for foot in FOOT_BODIES),
        )
    ]
    if model.njnt and model.jnt_type[0] == mujoco.mjtJoint.mjJNT_FREE:
        out.append(
            Plot(
                "pelvis_height",
                "pelvis height",
                "m",
                (Series(f"{record.TOPIC_STATE}.qpos[2]", "z"),),
            )
        )
    if pushes.wrench:
        lines = tuple(Series(f"{record.TOPIC_INPUTS}.{entity_part(b)}", b) for b in pushes.wrench)
        out.append(Plot("disturbance", "disturbance force", "N", lines))
    return tuple(out)


def _derived_series(
    contacts: _Wrenches, pushes: _Wrenches
) -> dict[str, tuple[np.ndarray, np.ndarray, tuple[int, int, int] | None]]:
    """The lines the export computes (path -> times, values, colour): a foot's normal force
    ``/sim/contacts.<foot>``, a disturbance's magnitude ``/sim/inputs.<body>``."""
    out: dict[str, tuple[np.ndarray, np.ndarray, tuple[int, int, int] | None]] = {}
    for foot, colour in zip(FOOT_BODIES, FOOT_COLOURS, strict=True):
        out[f"{record.TOPIC_CONTACTS}.{foot}"] = (contacts.t, contacts.wrench[foot][:, 2], colour)
    for body, wrench in pushes.wrench.items():
        magnitude = np.linalg.norm(wrench[:, :3], axis=1)
        out[f"{record.TOPIC_INPUTS}.{entity_part(body)}"] = (
            pushes.t,
            magnitude,
            DISTURBANCE_COLOUR,
        )
    return out


def _controller_plots(log: record.Log, controller: str) -> tuple[Plot, ...]:
    """The plots ``controller`` declares (``Plugin.plots``), or its scalar signals."""
    target = plugins.plot_declarations().get(controller)
    if target is not None:
        return tuple(plugins.load(target))  # type: ignore[arg-type]
    signals = log.arrays(record.TOPIC_SIGNALS)
    return signal_plots([k for k, v in signals.items() if k != "t" and v.ndim == 1])


def _send_plots(
    rr: Any,
    rec: Any,
    log: record.Log,
    plots: list[tuple[str, Plot]],
    derived: dict[str, tuple[np.ndarray, np.ndarray, tuple[int, int, int] | None]],
) -> list[str]:
    """Every line of ``plots`` (group, plot), each at the ticks where it is defined, named
    with its unit; a line of ``derived`` from there, the others from the log. Returns why
    each line the log does not have was left out."""
    cache: dict[str, dict[str, np.ndarray]] = {}
    skipped: list[str] = []
    for group, plot in plots:
        for series in plot.series:
            if series.path in derived:
                t, values, colour = derived[series.path]
            else:
                try:
                    (t, values), colour = read_series(log, series, cache), None
                except WalkreproError as exc:  # e.g. a log older than the declaration
                    skipped.append(str(exc))
                    continue
            entity = plot_entity(group, plot, series)
            style = rr.SeriesLines(
                names=f"{series.label} [{plot.unit}]", colors=None if colour is None else [colour]
            )
            rec.log(entity, style, static=True)
            rec.send_columns(
                entity,
                indexes=[rr.TimeColumn(TIMELINE, duration=t)],
                columns=rr.Scalars.columns(scalars=values),
            )
    return skipped


def _send_events(rr: Any, rec: Any, log: record.Log) -> None:
    """``/events`` as text lines: the kind, then the other fields."""
    events = log.messages(record.TOPIC_EVENTS)
    if not events:
        return
    t = np.array([e["t"] for e in events], dtype=float)
    text = [
        f"{e.get('kind', '?')}: "
        + ", ".join(f"{k} {v}" for k, v in e.items() if k not in ("t", "kind"))
        for e in events
    ]
    rec.send_columns(
        "events",
        indexes=[rr.TimeColumn(TIMELINE, duration=t)],
        columns=rr.TextLog.columns(text=text),
    )


def _verdict_text(check_file: Path) -> str:
    """A run's ``check.json`` as a Markdown table: one row per expectation."""
    try:
        check = json.loads(check_file.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        return f"(cannot read {check_file.name}: {exc})"
    from walkrepro.evaluation.checks import STATUS_WORDS

    lines = [
        f"# {check.get('experiment', '?')}: {check.get('outcome', '?')}, "
        f"{'every claim holds' if check.get('passed') else 'a claim failed'}",
        "",
        "| metric | paper | measured | verdict | source |",
        "|---|---|---|---|---|",
    ]
    for row in check.get("rows", []):
        measured = row.get("measured")
        value = (
            f"{measured:.4g}"
            if isinstance(measured, int | float) and math.isfinite(measured)
            else "not measurable"
        )
        status = row.get("status")
        word = STATUS_WORDS.get(status, status)
        cells = (row.get("metric"), row.get("band"), value, word, row.get("source"))
        lines.append("| " + " | ".join(str(c).replace("|", "/") for c in cells) + " |")
    return "\n".join(lines) + "\n"


def _blueprint(model: mujoco.MjModel, plots: list[tuple[str, Plot]], verdict: bool) -> Any:
    """The default layout: the 3D view (following the pelvis) over the verdict and the
    events, beside the plots."""
    import rerun.blueprint as rrb

    tracked = body_entity(TRACKED_BODY) if TRACKED_BODY in body_names(model) else None
    view3d = rrb.Spatial3DView(
        origin="world",
        name="robot",
        eye_controls=rrb.EyeControls3D(
            position=EYE_POSITION, look_target=EYE_TARGET, tracking_entity=tracked
        ),
        line_grid=rrb.LineGrid3D(visible=True, spacing=0.5),
    )
    texts = [rrb.TextLogView(origin="events", name="events")]
    if verdict:
        texts.insert(0, rrb.TextDocumentView(origin="verdict", name="verdict"))
    charts = [
        rrb.TimeSeriesView(origin=plot_entity(group, plot), name=plot.name) for group, plot in plots
    ]
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Vertical(view3d, rrb.Tabs(*texts), row_shares=[3, 1]),
            rrb.Vertical(*charts),
            column_shares=[3, 2],
        ),
        collapse_panels=True,
    )
