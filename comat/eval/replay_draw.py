"""What ``comat replay`` draws: a Rerun recording and a top-down video of a run beside its twin.

Both show, per env step, the real robots (what the script received) and the twin's (what its script
saw), and with ``--open-loop`` the logged commands played through the plant. The video draws each
frame as comat's own episodes are drawn (:func:`comat.envs.render.draw_frame`): the arena, the task's
objects (its areas and items, PCP's prey free / sensed / captured; each robot's capability rings and
bar), every real robot as a disc of its type's colour with its id and heading, and its trail; the
twin's robots on top as purple hollow rings with their ids, joined to the real ones by a grey line
(the divergence). The task's objects, the return and the filter's changes are the real run's: its
task logic replayed on the logged poses exactly as the exported ``main.py`` ran it, and its logged
commands before and after the filter (:func:`real_steps`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import rerun as rr

from comat import constants as C
from comat.envs.render import FRAME_SIZE, FrameState, draw_frame
from comat.envs.tap import MIN_CHANGE_MPS
from comat.runlog import RunLog
from comat.sim.kinematics import uni_to_si
from comat.tasks import task_entry
from comat.viz.video import VideoWriter

__all__ = ["real_steps", "record", "video"]

REAL_RGB, TWIN_RGB, OPEN_RGB = (30, 110, 220), (130, 40, 170), (120, 120, 120)
"""Colours of the real run, the twin and the open-loop playback in the recording."""
_DPI = 100


def _team(config: dict) -> tuple[list[str], np.ndarray, np.ndarray]:
    """The export's robot types (n,), their type ids (n,) and capabilities (n, C)."""
    logic = task_entry(config["task"]).logic
    types = list(config["types"])
    return types, np.array([logic.types.index(t) for t in types]), np.array(config["capabilities"], dtype=float)


def real_steps(log: RunLog, config: dict, steps: int) -> list[dict]:
    """What a frame shows of the real run at each of its first ``steps`` env-step starts, made from
    its log alone: the task's ``marks`` (:class:`comat.task_logic.Marks`) and the return so far, the
    task logic of the export's ``config`` reset, laid out and updated on the logged poses exactly as
    ``main.py`` does it (violations from the logged poses, as its own checks); and of the step before,
    where the filter changed a robot's command most (``intervened``, ``origin``, ``nominal``,
    ``filtered``: the logged commands before and after it, as velocities of the projected point) and
    where a robot left the arena or came within the collision distance (``events``, ``event_xy``)."""
    task = task_entry(config["task"]).logic(**config.get("task_options", {}))
    types, type_ids, caps = _team(config)
    n = len(types)
    state = task.new_state(1, n)
    task.reset_env(state, 0, np.random.default_rng(0), caps)
    task.set_layout(state, 0, config["layout"])
    task.set_starts(state, 0, np.array(config["start_poses"], dtype=float).T)
    mask = np.ones((1, n), dtype=bool)
    poses = np.asarray(log.poses, dtype=float)
    firsts = np.flatnonzero((log.actions >= 0).all(axis=1))[:steps]
    d = float(config.get("projection_distance_m", C.PROJECTION_DISTANCE_M))
    heading = np.stack([np.cos(poses[..., 2]), np.sin(poses[..., 2])], axis=-1)  # (K, N, 2)
    x0, x1, y0, y1 = C.ARENA_BOUNDS_M
    out = (poses[..., 0] < x0) | (poses[..., 0] > x1) | (poses[..., 1] < y0) | (poses[..., 1] > y1)
    hit = np.zeros_like(out)
    if n > 1:  # main.py's offset collisions, every pair of every iteration at once
        i, j = np.triu_indices(n, 1)
        centres = poses[..., :2] + config.get("collision_offset_m", C.COLLISION_OFFSET_M) * heading
        reach = config.get("collision_distance_m", C.COLLISION_DIAMETER_M)
        near = np.hypot(*(centres[:, i] - centres[:, j]).transpose(2, 0, 1)) <= reach
        incidence = np.zeros((i.size, n))
        incidence[np.arange(i.size), i] = incidence[np.arange(i.size), j] = 1.0
        hit = near.astype(float) @ incidence > 0
    u_nom, u = uni_to_si(log.nominal, poses, d), uni_to_si(log.sent, poses, d)
    change = np.linalg.norm(u - u_nom, axis=-1)  # (K, N)
    robots, ret = np.arange(n), 0.0
    zeros, none = np.zeros((n, 2)), np.zeros(n, dtype=bool)
    frames = [{"ret": 0.0, "intervened": none, "origin": zeros, "nominal": zeros, "filtered": zeros, "events": none}]
    frames[0].update(event_xy=zeros, marks=task.marks(state, 0, caps, type_ids))
    for k in range(1, firsts.size):
        rows = slice(firsts[k - 1], firsts[k])  # the iterations of env step k - 1
        raw = task.update(state, poses[firsts[k]][None], type_ids[None], caps[None], mask)
        raw["time"], raw["violation"] = np.ones(1), np.array([float((out[rows] | hit[rows]).any())])
        ret += sum(float(task.reward_weights[name] * raw[name][0]) for name in task.reward_terms)
        most = change[rows].argmax(axis=0)
        at = poses[rows][most, robots]
        events = out[rows] | hit[rows]
        frames.append(
            {
                "ret": ret,
                "intervened": change[rows].max(axis=0) > MIN_CHANGE_MPS,
                "origin": at[:, :2] + d * heading[rows][most, robots],
                "nominal": u_nom[rows][most, robots],
                "filtered": u[rows][most, robots],
                "events": events.any(axis=0),
                "event_xy": poses[rows][events.argmax(axis=0), robots, :2],
                "marks": task.marks(state, 0, caps, type_ids),
            }
        )
    return frames


def record(
    path: Path,
    real: np.ndarray,
    twin: np.ndarray,
    dist: np.ndarray,
    heading: np.ndarray,
    note: str,
    types: list[str],
    played: np.ndarray | None = None,
) -> None:
    """The runs (S, N, 3) in one recording (timeline ``step``; y mirrored as comat's recordings
    are): robots labelled with their id and type, trails, per-step divergence, ``note`` as text."""
    rec = rr.RecordingStream("comat", recording_id=f"replay-{path.stem}")
    x0, x1, y0, y1 = C.ARENA_BOUNDS_M
    rec.log("world", rr.Transform3D(scale=[1.0, -1.0, 1.0]), static=True)
    rec.log(
        "world/arena",
        rr.Boxes2D(
            centers=[((x0 + x1) / 2, (y0 + y1) / 2)], half_sizes=[((x1 - x0) / 2, (y1 - y0) / 2)], colors=[(60, 60, 60)]
        ),
        static=True,
    )
    rec.log("meta", rr.TextDocument(note, media_type=rr.MediaType.MARKDOWN), static=True)
    labels = [f"{i} {kind}" for i, kind in enumerate(types)]
    runs = [("real", real, REAL_RGB), ("twin", twin, TWIN_RGB)] + (
        [] if played is None else [("open_loop", played, OPEN_RGB)]
    )
    for k in range(real.shape[0]):
        rec.set_time("step", sequence=k)
        for name, poses, colour in runs:
            rec.log(f"world/{name}/robots", rr.Points2D(poses[k, :, :2], radii=[0.055], colors=[colour], labels=labels))
            trail = poses[: k + 1, :, :2].transpose(1, 0, 2)
            rec.log(f"world/{name}/trails", rr.LineStrips2D(list(trail), colors=[colour], radii=[0.005]))
        rec.log("divergence/position_mean_m", rr.Scalars(float(dist[k].mean())))
        rec.log("divergence/position_max_m", rr.Scalars(float(dist[k].max())))
        rec.log("divergence/heading_mean_rad", rr.Scalars(float(heading[k].mean())))
    rec.save(str(path))


def _figure():
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    h, w = FRAME_SIZE
    fig = Figure(figsize=(w / _DPI, h / _DPI), dpi=_DPI)
    FigureCanvasAgg(fig)
    return fig


def video(
    path: Path, log: RunLog, config: dict, real: np.ndarray, twin: np.ndarray, dist: np.ndarray, fps: int, title: str
) -> Path:
    """Both runs (S, N, 3) top-down, a frame per env step (module docstring), the step's divergence
    in the header (:class:`comat.viz.video.VideoWriter`: ``.mp4`` or ``.gif``)."""
    from matplotlib.patches import Circle

    logic = task_entry(config["task"]).logic
    types, _, caps = _team(config)
    frames = real_steps(log, config, real.shape[0])
    n = real.shape[1]
    radius = C.DEFAULT_PROFILE.radius_m
    fig = _figure()
    twin_rgb = tuple(c / 255 for c in TWIN_RGB)
    with VideoWriter(path, fps=fps) as writer:
        for k in range(real.shape[0]):
            state = FrameState(
                task=config["task"],
                poses=real[k],
                types=types,
                caps=caps,
                robot_radius_m=radius,
                trails=real[: k + 1, :, :2].transpose(1, 0, 2),
                type_colors=dict(logic.type_colors),
                step=k,
                horizon=logic.horizon,
                title=f"{title} · divergence {dist[k].mean() * 100:.1f} cm, max {dist[k].max() * 100:.1f}",
                **frames[k],
            )
            draw_frame(state, fig)
            ax = fig.axes[0]
            for i in range(n):  # the twin's robots: hollow rings with their ids, joined to the real ones
                (x, y, th), (rx, ry, _) = twin[k, i], real[k, i]
                ax.plot([rx, x], [ry, y], color="0.4", lw=0.8, zorder=8)
                ax.add_patch(Circle((x, y), radius, fill=False, edgecolor=twin_rgb, lw=1.6, zorder=8))
                ax.plot([x, x + 0.08 * np.cos(th)], [y, y + 0.08 * np.sin(th)], color=twin_rgb, lw=1.0, zorder=8)
                ax.text(x + radius, y + radius, str(i), fontsize=7, color=twin_rgb, zorder=9)
            fig.canvas.draw()
            writer.append(np.ascontiguousarray(np.asarray(fig.canvas.buffer_rgba())[..., :3]))
    return path
