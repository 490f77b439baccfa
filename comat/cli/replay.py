"""``comat replay LOG --export DIR``: a real run beside its simulated twin (:mod:`comat.eval.replay`).

Handlers import their floors when they run: ``comat --help`` loads neither torch nor Rerun.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
from pathlib import Path

from comat.cli.args import TIERS, add_force, add_reality

__all__ = ["add_replay_parser"]


def _cmd(args: argparse.Namespace) -> int:
    from comat.cli.args import reality_arg
    from comat.eval import check_options, check_twin, output_names
    from comat.eval import replay_log as replay
    from comat.files import new_outputs
    from comat.runlog import read_run_log
    from comat.viz.rollout import check_rrd_path
    from comat.viz.video import check_video_path
    from comat.viz.viewer import viewer_hint

    reality = reality_arg(args.reality)
    profiles = [reality_arg(p, "--profiles") for p in args.profiles]
    check_options(reality, profiles, args.k_steps, args.draws, args.envelope)
    log = read_run_log(args.log)  # a one-line error before anything runs
    if not Path(args.export).is_dir():
        raise ValueError(
            f"--export must be the exported folder the run came from, got {args.export!r} (no such folder)"
        )
    check_twin(log, Path(args.export))  # the folder is the run's, before anything is announced
    folder = Path(args.log) if Path(args.log).is_dir() else Path(args.log).parent
    out = check_rrd_path(args.out or folder / "replay.rrd", "--out", folder=False)
    names = output_names(out, args.envelope)
    video = None if args.video is None else check_video_path(args.video)
    print(
        f"comat replay: {args.log} ({log.n} robots, {len(log.t)} iterations, "
        f"{'ran to its end' if log.complete else 'cut short'}) beside its twin from {args.export} in MuJoCo "
        f"({args.tier} tier, reality {reality}); the plant of {', '.join(dict.fromkeys([reality, *profiles]))} "
        f"scored k = {', '.join(str(k) for k in sorted(set(args.k_steps)))} ticks ahead"
        + (f"; an envelope of {args.envelope} twins" if args.envelope else ""),
        file=sys.stderr,
    )
    with new_outputs(out.parent, names, force=args.force, flag="--out"):
        stack = contextlib.ExitStack()
        if video is not None:
            stack.enter_context(new_outputs(video.parent, [video.name], force=args.force, flag="--video"))
        with stack:
            result = replay(
                args.log,
                args.export,
                str(out),
                tier=args.tier,
                reality=reality,
                seed=args.seed,
                video=None if video is None else str(video),
                fps=args.fps,
                replay_commands=args.open_loop,
                profiles=profiles,
                k_steps=args.k_steps,
                draws=args.draws,
                envelope=args.envelope,
            )
    print(result["markdown"])
    for path in result["files"]:
        print(f"wrote {path}")
    print(viewer_hint(out))
    return 0


def add_replay_parser(subparsers) -> argparse.ArgumentParser:
    """``comat replay`` on the top-level sub-parsers."""
    p = subparsers.add_parser(
        "replay",
        help="a run's log (Robotarium or rps) beside its simulated twin, and the plant scored on it",
        description="Reads the log an exported main.py wrote (comat_run.npy and comat_run.meta.npy, "
        "docs/export.md) and runs its twin: the same team, prey and policy (the export folder --export, whose "
        "weights must be the run's) closed-loop in MuJoCo at --reality, from the poses the run logged first. "
        "Writes a Rerun recording of both (robots labelled with id and type, per-step position and heading "
        "divergence), a gap table (steps, return, progress, finished; divergence mean, p95, max; a sim-to-sim "
        "baseline) as Markdown and CSV, and the k-step prediction error of each profile's plant (the logged "
        "commands from each logged pose through the profile, against the pose logged k ticks later; per robot "
        "and in total, with a score that ranks profiles) as CSV beside it.",
    )
    p.add_argument("log", metavar="LOG", help="the run's log: its folder, or its comat_run.npy")
    p.add_argument("--export", required=True, metavar="DIR", help="the exported folder the run came from")
    p.add_argument(
        "--tier",
        choices=TIERS,
        default="unicycle",
        help="the twin's dynamics tier (default: %(default)s, as comat export --check: the presets' training tier)",
    )
    add_reality(p)
    p.add_argument(
        "--seed",
        type=int,
        default=0,
        help="the twin's reality-layer seed (default: %(default)s, that of export --check's first run)",
    )
    p.add_argument("--out", default=None, help="the recording, FILE.rrd (default: replay.rrd beside the log)")
    p.add_argument(
        "--video",
        default=None,
        metavar="FILE.mp4|FILE.gif",
        help="also draw both runs top-down into a video, a frame per env step",
    )
    p.add_argument(
        "--open-loop",
        action="store_true",
        help="also play the logged commands open-loop through --reality's plant from the logged first pose: "
        "how far the simulated robot alone drifts from the real one (rows in the gap table, mean over --draws; "
        "grey robots in the recording)",
    )
    p.add_argument(
        "--profiles",
        nargs="+",
        default=[],
        metavar="L|PROFILE.yaml",
        help="also score these levels or profiles' plants on the log (k-step table and a ranking by score)",
    )
    p.add_argument(
        "--k-steps",
        type=int,
        nargs="+",
        default=[1, 5, 30],
        metavar="K",
        help="the k-step prediction horizons, in ticks of 0.033 s (default: 1 5 30)",
    )
    p.add_argument(
        "--draws",
        type=int,
        default=8,
        help="draws of a profile's randomness per k-step start and in --open-loop (default: %(default)s; one at off)",
    )
    p.add_argument(
        "--envelope",
        type=int,
        default=0,
        metavar="N",
        help="also run N >= 20 twins under the profile's randomness (seeds --seed …): the real outcome's "
        "percentile among them per task metric (default: 0, none; each twin is a closed-loop episode)",
    )
    p.add_argument("--fps", type=int, default=5, help="--video: frames (env steps) per second (default: %(default)s)")
    add_force(p)
    p.set_defaults(func=_cmd)
    return p
