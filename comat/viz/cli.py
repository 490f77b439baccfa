"""Command-line pieces of ``comat`` that live with the recorder: ``rollout`` and ``bench viz``.

``comat/cli.py`` registers them::

    add_rollout_parser(sub)     # sub: the top-level subparsers  -> comat rollout
    add_viz_bench_parser(bsub)  # bsub: the ``bench`` subparsers -> comat bench viz

Each parser sets ``func`` to its handler, which returns an exit code and raises ValueError /
TypeError (printed by ``comat.cli.main`` as ``comat <command>: error: …``) for bad input, before
anything runs.
"""

from __future__ import annotations

import argparse
import shlex
import sys
import time

from comat.team import COALITION_SETS

__all__ = ["add_rollout_parser", "add_viz_bench_parser", "cmd_rollout", "cmd_viz_bench"]


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}")
    return value


def cmd_rollout(args: argparse.Namespace) -> int:
    """``comat rollout``: record episodes to ``--out`` and print how to open the file."""
    from comat.viz.rollout import POLICY_NAMES, check_rrd_path, record_episodes, resolve_policy

    # Every check first (output path, then policy and its task), so nothing is announced in vain.
    default = f"{args.task}_{args.policy if args.policy in POLICY_NAMES else 'checkpoint'}.rrd"
    out = check_rrd_path(args.out or default) if args.out or not args.video else None
    policy = resolve_policy(args.policy, args.task)
    print(
        f"comat rollout: {args.task}, policy {policy.name}, {args.episodes} episode(s) from the {args.set} "
        f"coalitions, seed {args.seed} -> {', '.join(str(p) for p in (out, args.video) if p)}",
        file=sys.stderr,
    )
    t0 = time.perf_counter()
    result = record_episodes(
        out,
        args.task,
        policy,
        episodes=args.episodes,
        coalitions=args.set,
        seed=args.seed,
        tier=args.tier,
        ticks_per_step=args.ticks_per_step,
        video=args.video,
        fps=args.fps,
    )
    for k, e in enumerate(result.episodes):
        print(
            f"  episode {k}: {int(e['team_size'])} robots, {int(e['steps'])} steps, return {e['return']:.2f}, "
            f"completion {e['completion']:.0%}, collisions {int(e['collisions'])}, "
            f"filter interventions {int(e['interventions'])}"
        )
    if result.video is not None:
        frames = sum(int(e["steps"]) + 1 for e in result.episodes)
        print(f"wrote {result.video} ({result.video.stat().st_size / 1024:.0f} KiB, {frames} frames at {args.fps} fps)")
    if result.path is not None:
        print(
            f"wrote {result.path} ({result.bytes / 1024:.0f} KiB, {result.bytes_per_robot_step:.0f} B per "
            f"robot-step, {time.perf_counter() - t0:.1f} s)"
        )
        print(f"open it with: rerun {shlex.quote(str(result.path))}")
    return 0


def add_rollout_parser(subparsers) -> argparse.ArgumentParser:
    """Register ``rollout`` on the top-level ``subparsers`` of the ``comat`` parser."""
    p = subparsers.add_parser(
        "rollout",
        help="record episodes of a policy to a Rerun .rrd file",
        description="Run a policy (the scripted heuristic, random actions, or a checkpoint from `comat train`) for "
        "some episodes and record them to one .rrd file: the arena and task zones, each robot with its type and "
        "capabilities, its trail, the action it chose, where the safety filter changed its command, contacts "
        "and collisions, prey or material, and the reward terms over time. One tab per episode. "
        "Open the file with `rerun FILE.rrd`.",
    )
    p.add_argument("--task", choices=["pcp", "hmt"], required=True, help="task")
    p.add_argument(
        "--policy",
        default="heuristic",
        help="'heuristic', 'random', or the path of a checkpoint.pt trained on --task (default: %(default)s)",
    )
    p.add_argument(
        "--episodes", type=_positive_int, default=3, help="episodes to record (default: %(default)s)"
    )
    p.add_argument(
        "--set",
        choices=list(COALITION_SETS),
        default="test",
        help="coalition set the teams are drawn from (default: %(default)s, teams unseen in training)",
    )
    p.add_argument(
        "--seed", type=int, default=0, help="episode k resets with seed + k (default: %(default)s)"
    )
    p.add_argument(
        "--tier",
        choices=["wheels", "unicycle"],
        default=None,
        help="dynamics tier (default: the checkpoint's, else wheels)",
    )
    p.add_argument(
        "--ticks-per-step",
        type=_positive_int,
        default=None,
        help="control ticks per env step (default: the task's, PCP 29, HMT 74)",
    )
    p.add_argument(
        "--out",
        default=None,
        help="output .rrd file; its folder must exist (default: <task>_<policy>.rrd; none with --video alone)",
    )
    p.add_argument(
        "--video",
        default=None,
        metavar="FILE.mp4|FILE.gif",
        help="also write the episodes as a video drawn top-down with matplotlib (headless; one frame per env "
        "step): .mp4 (H.264) or .gif",
    )
    p.add_argument("--fps", type=_positive_int, default=10, help="video frames per second (default: %(default)s)")
    p.set_defaults(func=cmd_rollout)
    return p


def cmd_viz_bench(args: argparse.Namespace) -> int:
    """``comat bench viz``: recording overhead and file size; JSON to ``--out`` plus a table."""
    from comat.viz.bench import run_viz_bench

    print(
        f"comat bench viz: {', '.join(args.tasks)}, {args.episodes} episode(s) of the {args.policy} policy, "
        f"{args.tier} tier, {args.repeats} repeats each way",
        file=sys.stderr,
    )
    run_viz_bench(
        tuple(args.tasks),
        tier=args.tier,
        policy=args.policy,
        episodes=args.episodes,
        repeats=args.repeats,
        seed=args.seed,
        out=args.out,
    )
    return 0


def add_viz_bench_parser(bench_subparsers) -> argparse.ArgumentParser:
    """Register ``viz`` on the ``bench`` subparsers of the ``comat`` parser."""
    b = bench_subparsers.add_parser(
        "viz",
        help="cost of recording a rollout to .rrd (time overhead, bytes per robot-step)",
        description="Run the same rollouts with and without Rerun recording, alternating, and report the median "
        "time overhead and the file size per robot-step.",
    )
    b.add_argument("--tasks", nargs="+", choices=["pcp", "hmt"], default=["pcp", "hmt"])
    b.add_argument(
        "--tier",
        choices=["wheels", "unicycle"],
        default="unicycle",
        help="dynamics tier (default: %(default)s)",
    )
    b.add_argument(
        "--policy", default="heuristic", help="'heuristic', 'random' or a checkpoint (default: %(default)s)"
    )
    b.add_argument(
        "--episodes", type=_positive_int, default=3, help="episodes per rollout (default: %(default)s)"
    )
    b.add_argument(
        "--repeats", type=_positive_int, default=5, help="rollouts each way (default: %(default)s)"
    )
    b.add_argument("--seed", type=int, default=0, help="seed of the first episode (default: %(default)s)")
    b.add_argument("--out", default="benchmarks/results/viz.json", help="JSON output (default: %(default)s)")
    b.set_defaults(func=cmd_viz_bench)
    return b
