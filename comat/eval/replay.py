"""A real run beside its simulated twin: ``comat replay LOG --export DIR``.

The run's log (:mod:`comat.runlog`, what the exported ``main.py`` saw and did on the Robotarium, or
under ``rps`` standing in for it) is laid next to the same team, start poses, prey and policy run
closed-loop in comat's MuJoCo world (:func:`sim2real.check.mujoco_twin`) at a reality level or a
calibrated profile. Both are compared at every env step's start, like with like: the poses the real
script received (the real run has no others) against those the twin's script saw (its true poses
seen through its reality layer: the true ones at ``off``), and at the end (the task metrics):

* a Rerun recording: the arena, each robot of the real run (solid) and of the twin (hollow) with
  their trails, and per step the position and heading divergence (mean and max over robots);
* a gap table (CSV and Markdown): steps, return, progress, finished, and the divergence's mean,
  95th percentile and maximum over steps.

The twin must be the run's: the export folder's weights have the sha256 the log records and its
team, start poses and prey are the log's (else one line says which differs).
"""

from __future__ import annotations

import csv
import hashlib
import io
from pathlib import Path

import numpy as np
import rerun as rr

from comat import constants as C
from comat.config import SimConfig
from comat.files import write_atomic
from comat.runlog import RunLog, read_run_log
from comat.sim import World
from comat.viz.video import VideoWriter
from sim2real.check import mujoco_twin
from sim2real.export import layout_of, load_config

__all__ = [
    "GAP_METRICS",
    "ReplayError",
    "check_twin",
    "deployed_loop_of",
    "gap_rows",
    "open_loop",
    "replay",
    "step_poses",
]

GAP_METRICS = ("steps", "return", "progress", "finished")
"""Task metrics the gap table puts side by side (the real run's from its log's result)."""
_REAL, _TWIN, _OPEN = (30, 110, 220), (240, 140, 30), (120, 120, 120)


class ReplayError(ValueError):
    """A log and an export folder that do not belong together (one line: what differs)."""


def check_twin(log: RunLog, export: Path) -> dict:
    """The export folder's CONFIG once it is known to be the run's: the same policy weights, team,
    start poses and prey (ReplayError naming what differs)."""
    config = load_config(export)
    meta = log.meta
    weights = export / "weights.npy"
    sha = hashlib.sha256(weights.read_bytes()).hexdigest() if weights.is_file() else "heuristic"
    if meta.get("policy_sha256") not in (None, sha):
        raise ReplayError(
            f"--export {str(export)!r}: its policy (sha256 {sha[:12]}…) is not the one the run logged "
            f"({str(meta['policy_sha256'])[:12]}…)"
        )
    for key in ("task", "types", "capabilities", "ticks_per_step"):
        if meta.get(key) != config.get(key):
            raise ReplayError(
                f"--export {str(export)!r}: {key} {config.get(key)!r}, but the run logged {meta.get(key)!r}"
            )
    start = np.asarray(meta["start_poses"], dtype=float)
    if start.shape != np.shape(config["start_poses"]) or not np.allclose(start, config["start_poses"], atol=1e-9):
        raise ReplayError(f"--export {str(export)!r}: its start poses are not the run's")
    logged, want = layout_of(meta), layout_of(config)
    for key in sorted(set(logged) | set(want)):
        a, b = np.asarray(logged.get(key, []), dtype=float), np.asarray(want.get(key, []), dtype=float)
        if a.shape != b.shape or not np.allclose(a, b, atol=1e-9):
            raise ReplayError(f"--export {str(export)!r}: its task layout ({key}) is not the run's")
    return config


def open_loop(log: RunLog, tier: str = "unicycle") -> np.ndarray:
    """(S, N, 3) the poses MuJoCo's robots reach, at each env step's start, when the run's logged
    commands (as sent) are played to them open-loop from its start poses: how far the simulated robot
    alone, without the policy or the filter in the loop, departs from what the real one did."""
    world = World(log.n, SimConfig(tier=tier))
    world.reset(np.asarray(log.meta["start_poses"], dtype=float).T)
    starts = (log.actions >= 0).all(axis=1)
    out = []
    for k in range(len(log.t)):
        if starts[k]:
            out.append(world.poses)
        world.step(log.sent[k].astype(float))
    return np.stack(out)


def deployed_loop_of(meta: dict) -> str:
    """The loop the logged run ran, as comat runs it (:data:`comat.config.LOOPS`): its filter under its
    rps generation's constants, so the twin's commands are the run's for the same poses."""
    generation = "v2" if meta.get("rps") == "v2" else "legacy"
    return f"{'shipped' if meta.get('filter', 'comat') == 'comat' else 'robotarium'}_{generation}"


def step_poses(log: RunLog) -> np.ndarray:
    """(S, N, 3) the poses the real run's script received where each env step started."""
    return log.poses[(log.actions >= 0).all(axis=1)]


def _divergence(real: np.ndarray, twin: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per step and robot: position distance (m) and heading difference (rad), (S, N) each."""
    dist = np.hypot(*(real[..., :2] - twin[..., :2]).transpose(2, 0, 1))
    heading = np.abs(np.angle(np.exp(1j * (real[..., 2] - twin[..., 2]))))
    return dist, heading


def gap_rows(log: RunLog, twin: dict, dist: np.ndarray) -> list[dict]:
    """The gap table: the task metrics of the real run and its twin, and the position divergence."""
    real = log.meta.get("result") or {}
    rows = []
    for name in GAP_METRICS:
        r, t = real.get(name), float(twin["metrics"][name])
        rows.append({"quantity": name, "real": r, "twin": t, "gap": None if r is None else float(r) - t})
    per_step = dist.mean(axis=1)
    for label, value in (("mean", per_step.mean()), ("p95", np.percentile(per_step, 95)), ("max", dist.max())):
        rows.append({"quantity": f"position divergence {label} (m)", "real": None, "twin": None, "gap": float(value)})
    return rows


def _table(rows: list[dict], note: str) -> tuple[str, str]:
    def cell(v):
        return "" if v is None else f"{v:.4g}" if isinstance(v, float) else str(v)

    md = ["| quantity | real | twin | real − twin |", "|---|---|---|---|"]
    md += [f"| {r['quantity']} | {cell(r['real'])} | {cell(r['twin'])} | {cell(r['gap'])} |" for r in rows]
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=["quantity", "real", "twin", "gap"], lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    return "\n".join(md) + f"\n\n{note}\n", buf.getvalue()


def _record(
    path: Path,
    real: np.ndarray,
    twin: np.ndarray,
    dist: np.ndarray,
    heading: np.ndarray,
    note: str,
    played: np.ndarray | None = None,
) -> None:
    """The two runs in one recording (timeline ``step``; y mirrored as comat's recordings are)."""
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
    n = real.shape[1]
    labels = [f"robot_{i}" for i in range(n)]
    for k in range(real.shape[0]):
        rec.set_time("step", sequence=k)
        runs = [("real", real, _REAL), ("twin", twin, _TWIN)] + (
            [] if played is None else [("open_loop", played, _OPEN)]
        )
        for name, poses, colour in runs:
            rec.log(f"world/{name}/robots", rr.Points2D(poses[k, :, :2], radii=[0.055], colors=[colour], labels=labels))
            trail = poses[: k + 1, :, :2].transpose(1, 0, 2)
            rec.log(f"world/{name}/trails", rr.LineStrips2D(list(trail), colors=[colour], radii=[0.005]))
        rec.log("divergence/position_mean_m", rr.Scalars(float(dist[k].mean())))
        rec.log("divergence/position_max_m", rr.Scalars(float(dist[k].max())))
        rec.log("divergence/heading_mean_rad", rr.Scalars(float(heading[k].mean())))
    rec.save(str(path))


def _video(path: Path, real: np.ndarray, twin: np.ndarray, dist: np.ndarray, fps: int) -> Path:
    """Both runs top-down, a frame per env step: the real robots filled, the twin's hollow, their
    trails, and the step's mean divergence in the title (:class:`comat.viz.video.VideoWriter`)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    x0, x1, y0, y1 = C.ARENA_BOUNDS_M
    fig = Figure(figsize=(6.4, 4.48), dpi=100)
    canvas = FigureCanvasAgg(fig)
    with VideoWriter(path, fps=fps) as writer:
        for k in range(real.shape[0]):
            fig.clear()
            ax = fig.add_axes((0.02, 0.02, 0.96, 0.88))
            ax.set_xlim(x0 - 0.05, x1 + 0.05)
            ax.set_ylim(y0 - 0.05, y1 + 0.05)
            ax.set_aspect("equal")
            ax.set_xticks([])
            ax.set_yticks([])
            ax.plot([x0, x1, x1, x0, x0], [y0, y0, y1, y1, y0], color="0.3", lw=1)
            for poses, colour, filled, name in ((real, _REAL, True, "real"), (twin, _TWIN, False, "twin")):
                c = np.array(colour) / 255
                for i in range(poses.shape[1]):
                    ax.plot(poses[: k + 1, i, 0], poses[: k + 1, i, 1], color=c, lw=0.8, alpha=0.6)
                ax.scatter(
                    poses[k, :, 0],
                    poses[k, :, 1],
                    s=60,
                    facecolors=c if filled else "none",
                    edgecolors=c,
                    linewidths=1.5,
                    label=name,
                )
            ax.legend(loc="lower right", fontsize=7)
            fig.suptitle(
                f"step {k}: position divergence mean {dist[k].mean() * 100:.1f} cm, max {dist[k].max() * 100:.1f} cm",
                fontsize=9,
            )
            canvas.draw()
            writer.append(np.ascontiguousarray(np.asarray(canvas.buffer_rgba())[..., :3]))
    return path


def replay(
    log_path: str,
    export: str,
    out: str,
    tier: str = "unicycle",
    reality: str = "off",
    seed: int = 0,
    video: str | None = None,
    fps: int = 5,
    replay_commands: bool = False,
) -> dict:
    """Lay the run logged at ``log_path`` beside its twin from the export folder ``export`` (module
    docstring); writes ``out`` (``.rrd``) and the gap table beside it (``<stem>_gap.md``/``.csv``), and
    with ``video`` (``.mp4``/``.gif``) both runs drawn top-down, a frame per env step at ``fps``.
    ``replay_commands``: also the logged commands played open-loop (:func:`open_loop`), their
    divergence in the table and their robots in the recording.

    Returns ``{"rows": gap rows, "steps": compared steps, "complete": the run finished, "files": [...]}``.

    Raises:
        comat.runlog.RunLogError: the log cannot be read; ReplayError: the folder is not the run's.
    """
    log = read_run_log(log_path)
    export_dir = Path(export)
    check_twin(log, export_dir)
    loop = deployed_loop_of(log.meta)
    twin = mujoco_twin(export_dir, tier=tier, reality=None if reality == "off" else reality, seed=seed, loop=loop)
    real = step_poses(log)
    steps = min(len(real), len(twin["poses"]))
    if steps == 0:
        raise ReplayError(f"{log_path}: the log holds no env step start to compare (a run stopped at once)")
    real, twin_poses = real[:steps], twin["measured"][:steps]
    dist, heading = _divergence(real, twin_poses)
    rows = gap_rows(log, twin, dist)
    played = None
    if replay_commands:
        played = open_loop(log, tier)[:steps]
        open_dist = _divergence(real, played)[0]
        rows += [
            {"quantity": f"open-loop divergence {label} (m)", "real": None, "twin": None, "gap": float(value)}
            for label, value in (("mean", open_dist.mean()), ("max", open_dist.max()))
        ]
    note = (
        f"Real run: {log.meta.get('task')} with {log.n} robots under rps {log.meta.get('rps')} "
        f"({'finished' if log.complete else 'cut short: no result, compared as far as it logged'}), "
        f"{len(log.t)} iterations. Twin: the same team, start and policy in MuJoCo ({tier} tier, reality "
        f"{reality}, the run's loop {loop}). Divergence: the poses the real script received against those the twin's "
        f"script saw, at the start of each of {steps} env steps."
    )
    md, table_csv = _table(rows, note)
    out_path = Path(out)
    files = [out_path, out_path.with_name(out_path.stem + "_gap.md"), out_path.with_name(out_path.stem + "_gap.csv")]
    _record(files[0], real, twin_poses, dist, heading, md, played)
    write_atomic(files[1], md)
    write_atomic(files[2], table_csv)
    if video is not None:
        files.append(_video(Path(video), real, twin_poses, dist, fps))
    return {"rows": rows, "steps": steps, "complete": log.complete, "files": files, "markdown": md}
