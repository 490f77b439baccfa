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
import sys
import time

from comat.cli.args import int_at_least
from comat.viz.viewer import viewer_hint

__all__ = ["add_rollout_parser", "add_viz_bench_parser", "cmd_rollout", "cmd_viz_bench"]

_positive_int = int_at_least(1)


def cmd_rollout(args: argparse.Namespace) -> int:
    """``comat rollout``: record episodes to ``--out`` (and/or ``--video``) and print how to open them."""
    import contextlib
    from pathlib import Path

    from comat.cli.args import parse_team, parse_teams, reality_arg, resolve_policy_arg
    from comat.files import new_outputs
    from comat.viz.rollout import check_rrd_path, record_episodes
    from comat.viz.video import check_video_path

    # Every check first (policy and its task, teams, output paths), so nothing is announced in vain.
    reality = reality_arg(args.reality)
    pol = resolve_policy_arg(args.policy, args.task)
    task = pol.task
    if args.team is not None:
        team = parse_team(args.team, task)
        teams, coalitions, source = [team] * args.episodes, "train", f"the team {args.team}"
    else:
        named = parse_teams(args.teams, task)
        teams, coalitions = None, [t for _, ts in named for t in ts]
        source = f"the {args.teams} coalitions"
    video = None if args.video is None else check_video_path(args.video)
    stem = args.policy if pol.checkpoint is None else "checkpoint"
    out = None
    if args.out or video is None:
        out = check_rrd_path(args.out or f"{task}_{stem}.rrd", "--out", folder=False)
    tier = args.tier or pol.tier
    print(
        f"comat rollout: {task}, policy {pol.label}, {args.episodes} episode(s) from {source}, {tier} tier, "
        f"seed {args.seed}, reality {reality} -> {', '.join(str(p) for p in (out, video) if p)}",
        file=sys.stderr,
    )
    t0 = time.perf_counter()
    with contextlib.ExitStack() as stack:
        for path in (out, video):
            if path is not None:
                stack.enter_context(
                    new_outputs(
                        Path(path).parent,
                        [Path(path).name],
                        force=args.force,
                        flag="--out" if path is out else "--video",
                    )
                )
        if out is not None:
            check_rrd_path(out, "--out")  # its folder exists now: writable?
        result = record_episodes(
            out,
            task,
            str(pol.checkpoint or pol.name),
            episodes=args.episodes,
            teams=teams,
            coalitions=coalitions,
            seed=args.seed,
            tier=tier,
            ticks_per_step=args.ticks_per_step,
            video=video,
            fps=args.fps,
            reality=reality,
        )
    for k, e in enumerate(result.episodes):
        print(
            f"  episode {k}: {int(e['team_size'])} robots, {int(e['steps'])} steps, return {e['return']:.2f}, "
            f"progress {e['progress']:.0%}, collisions {int(e['collisions'])}, "
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
        print(viewer_hint(result.path))
    return 0


def add_rollout_parser(subparsers) -> argparse.ArgumentParser:
    """Register ``rollout`` on the top-level ``subparsers`` of the ``comat`` parser."""
    from comat.cli.args import (
        add_force,
        add_policy,
        add_reality,
        add_seed,
        add_task,
        add_team,
        add_teams,
        add_tier,
    )

    p = subparsers.add_parser(
        "rollout",
        help="record episodes of a policy to a Rerun .rrd file and/or a video",
        description="Run a policy (a checkpoint or run folder from `comat train`, the scripted heuristic, random or "
        "constant actions) for some episodes and record them to one .rrd file: the arena and task zones, each robot "
        "with its type and capabilities, its trail, the action it chose, where the safety filter changed its "
        "command, contacts and collisions, prey or material, and the reward terms over time. One tab per episode. "
        "Open the file with `rerun FILE.rrd`. With --video, the same episodes drawn top-down as .mp4 or .gif.",
    )
    add_policy(p)
    add_task(p)
    add_teams(p)
    add_team(p, note=" (instead of --teams)")
    p.add_argument("--episodes", type=_positive_int, default=1, help="episodes to record (default: %(default)s)")
    add_tier(p)
    add_seed(p, "episode k resets with seed + k")
    add_reality(p)
    p.add_argument(
        "--ticks-per-step",
        type=_positive_int,
        default=None,
        help="control ticks per env step (default: the task's, PCP 29, HMT 74)",
    )
    p.add_argument(
        "--out",
        default=None,
        metavar="FILE.rrd",
        help="output .rrd file; its folder is created if missing (default: <task>_<policy>.rrd; none with "
        "--video alone)",
    )
    p.add_argument(
        "--video",
        default=None,
        metavar="FILE.mp4|FILE.gif",
        help="also write the episodes as a video drawn top-down with matplotlib (headless; one frame per env "
        "step): .mp4 (H.264) or .gif",
    )
    p.add_argument("--fps", type=_positive_int, default=10, help="video frames per second (default: %(default)s)")
    add_force(p)
    p.set_defaults(func=cmd_rollout)
    return p


def cmd_viz_bench(args: argparse.Namespace) -> int:
    """``comat bench viz``: recording overhead and file size; JSON to ``--out`` plus a table."""
    from comat.cli.args import REFERENCE_POLICIES, TASKS, resolve_policy_arg
    from comat.viz.bench import run_viz_bench

    if args.policy in REFERENCE_POLICIES:
        tasks, policy, tier = (
            tuple(args.tasks or TASKS),
            args.policy,
            args.tier or resolve_policy_arg(args.policy, "pcp").tier,
        )
    else:  # a checkpoint plays its own task
        pol = resolve_policy_arg(args.policy, None)
        if args.tasks and args.tasks != [pol.task]:
            raise ValueError(f"--tasks {args.tasks} disagrees with the checkpoint, which is for task {pol.task!r}")
        tasks, policy, tier = (pol.task,), str(pol.checkpoint), args.tier or pol.tier
    print(
        f"comat bench viz: {', '.join(tasks)}, {args.episodes} episode(s) of the {args.policy} policy, "
        f"{tier} tier, {args.repeats} repeats each way",
        file=sys.stderr,
    )
    run_viz_bench(
        tasks,
        tier=tier,
        policy=policy,
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
    from comat.cli.args import TASKS, add_policy, add_seed, add_tier

    b.add_argument(
        "--tasks",
        nargs="+",
        choices=TASKS,
        default=None,
        help=f"tasks (default: {' '.join(TASKS)}; a checkpoint's own task)",
    )
    add_tier(b)
    add_policy(b)
    b.add_argument("--episodes", type=_positive_int, default=3, help="episodes per rollout (default: %(default)s)")
    b.add_argument("--repeats", type=_positive_int, default=5, help="rollouts each way (default: %(default)s)")
    add_seed(b, "seed of the first episode")
    b.add_argument("--out", default="benchmarks/results/viz.json", help="JSON output (default: %(default)s)")
    b.set_defaults(func=cmd_viz_bench)
    return b
