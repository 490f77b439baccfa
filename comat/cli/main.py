"""The ``comat`` command line: ``comat <command> --help`` documents each command.

Commands, by the module that declares and runs them:

* :mod:`comat.cli.train`: ``train`` (any learner on any registered task), ``policy`` (a run's policy file);
* :mod:`comat.cli.evaluate`: ``eval``, ``probe``, ``report``, ``sweep``;
* :mod:`comat.cli.rollout`: ``rollout`` (Rerun recordings and videos);
* :mod:`comat.cli.export`: ``export`` (Robotarium submissions, ``--check``);
* :mod:`comat.cli.replay`: ``replay`` (a run's log beside its simulated twin);
* :mod:`comat.cli.campaign`: ``campaign`` (a hardware campaign's folders, and ``--analyze`` what comes back);
* :mod:`comat.cli.calibrate`: ``calibrate`` (fit the reality layer to calibration logs);
* :mod:`comat.cli.bench`: ``bench`` (sim, env, learn, soak, fidelity, safety, viz);
* :mod:`comat.cli.tasks`: ``tasks`` (the registered tasks), ``validity`` (the reference ladder and the families);
* here: ``demo`` (:mod:`comat.cli.demo`), ``mjcf`` (the golden MJCF files), ``coalitions``.

Handlers import the floors they need when they run: ``comat --help`` loads neither torch nor Rerun.
"""

from __future__ import annotations

import argparse
import os
import sys

from comat.cli.args import TIERS, CommandParser, VersionAction
from comat.cli.bench import add_bench_parser
from comat.cli.calibrate import add_calibrate_parser
from comat.cli.campaign import add_campaign_parser
from comat.cli.evaluate import add_evaluate_parsers
from comat.cli.export import add_export_parser
from comat.cli.replay import add_replay_parser
from comat.cli.rollout import add_rollout_parser
from comat.cli.tasks import add_tasks_parsers
from comat.cli.train import add_train_parsers
from comat.learners import plugin_error as learner_plugin_error
from comat.machine import RunRegistry, set_thread_waiting
from comat.tasks import plugin_error
from comat.team import COALITION_SETS, COALITIONS_DIR

__all__ = ["build_parser", "main"]


def _single_thread() -> None:
    # Benchmarks and rollouts are measured on one core unless the user says otherwise.
    for var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
        os.environ.setdefault(var, "1")
    # Idle torch threads spin a little, then sleep (at once where other trainings run): spinning,
    # two runs steal each other's cores; sleeping at once, a lone run's update waits for its
    # threads to wake (comat/machine.py).
    set_thread_waiting(others_training=bool(RunRegistry("", 0).others()))


def _cmd_mjcf(args: argparse.Namespace) -> int:
    from comat.mjcf import write_assets

    for path in write_assets(args.out):
        print(f"wrote {path}")
    return 0


def _cmd_coalitions(args: argparse.Namespace) -> int:
    from pathlib import Path

    from comat.team import CAPABILITY_RANGES, SET_LABELS, generate_coalitions, save_coalitions

    # What each file's first line says its set is (the paper's two sets keep their old header).
    about = {
        "train": "(paper §III-D)",
        "test": "(paper §III-D)",
        "scale": "(sizes 10-20, U_test's capability ranges)",
        "val": "(drawn like U_train, no U_train team; the only set for model selection)",
        "size": "(sizes 2-20, two of each, the training capability ranges)",
        "capability": "(sizes 3/5/7, every capability outside the training range)",
    }
    for task, split in sorted(CAPABILITY_RANGES):
        teams = generate_coalitions(task, split, args.count, args.seed)
        path = Path(args.out) / f"{task}_{split}.yaml"
        save_coalitions(
            teams,
            path,
            header=f"comat coalitions --seed {args.seed} --count {args.count}: "
            f"{SET_LABELS[split]} for {task} {about[split]}",
        )
        sizes = sorted({t.size for t in teams})
        print(f"wrote {path}: {len(teams)} teams, sizes {sizes}")
    return 0


def _cmd_demo(args: argparse.Namespace) -> int:
    from comat.cli.demo import run_demo

    return run_demo(
        tier=args.tier,
        robots=args.robots,
        episodes=args.episodes,
        seed=args.seed,
        out=args.out,
        part=args.part,
        folder=args.folder,
        command=main,
    )


def _add_coalitions_parser(sub) -> None:
    p = sub.add_parser(
        "coalitions",
        help="regenerate the team composition sets (" + ", ".join(COALITION_SETS) + ")",
        description="Write every composition set (U_train, U_val, U_test, U_scale, U_size, U_cap; "
        "20 coalitions each, per task; what each holds: comat.team) from a seed as YAML; the "
        "environments use the same teams (seed 0).",
    )
    p.add_argument("--seed", type=int, default=0, help="seed (default: %(default)s; the envs use 0)")
    p.add_argument("--count", type=int, default=20, help="coalitions per set (default: %(default)s)")
    p.add_argument(
        "--out",
        default=str(COALITIONS_DIR),
        help="output folder (default: the package's copies, train/coalitions/ in a checkout)",
    )
    p.set_defaults(func=_cmd_coalitions)


def _add_mjcf_parser(sub) -> None:
    p = sub.add_parser(
        "mjcf",
        help="write the generated MJCF files (robot, arena, scenes)",
        description="Regenerate the checked-in MJCF files from comat.mjcf (never edit them by hand).",
    )
    p.add_argument("--out", default="assets/mjcf", help="output folder (default: %(default)s)")
    p.set_defaults(func=_cmd_mjcf)


def build_parser() -> argparse.ArgumentParser:
    parser = CommandParser(
        prog="comat",
        description="MuJoCo Sim2Real testbed for heterogeneous robot teams on the Robotarium.",
    )
    parser.add_argument("--version", action=VersionAction, help="print the version (and source commit) and exit")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    # In a newcomer's order, as docs/commands.md lists them: try, train, judge, watch, deploy and bring
    # back, the sets and tasks, the tools.
    p = sub.add_parser(
        "demo",
        help="robots crossing paths under the safety filter; the tasks; a trained policy",
        description="1) Teams of robots swap places through the arena centre, every command passing "
        "the barrier filter; the same episodes without the filter show what it prevents. 2) The scripted "
        "heuristic and a random policy on every registered task, training and unseen coalitions. 3) The COMAT "
        "policy that ships with comat plays unseen PCP teams: a Rerun recording, a video and a checked "
        "Robotarium export in --folder. --part train: a quick COMAT trains on PCP (5-10 minutes) and plays "
        "the training and unseen coalitions next to a random policy.",
    )
    p.add_argument("--tier", choices=TIERS, default="wheels", help="dynamics tier (default: %(default)s)")
    p.add_argument("--robots", type=int, default=8, help="robots per team (default: %(default)s)")
    p.add_argument("--episodes", type=int, default=3, help="teams / coalitions per row (default: %(default)s)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default: %(default)s)")
    p.add_argument(
        "--part",
        choices=["all", "physics", "tasks", "pretrained", "train"],
        default="all",
        help="which part to run (default: all = physics, tasks, pretrained)",
    )
    p.add_argument(
        "--folder",
        default="runs/demo",
        help="where the pretrained part writes its recording, video and export (default: %(default)s)",
    )
    p.add_argument("--out", default=None, help="also write the summary as JSON to this file")
    p.set_defaults(func=_cmd_demo)

    add_train_parsers(sub)  # train, policy
    add_evaluate_parsers(sub)  # eval, probe, report, sweep
    add_rollout_parser(sub)
    add_export_parser(sub)
    add_replay_parser(sub)
    add_campaign_parser(sub)
    add_calibrate_parser(sub)
    _add_coalitions_parser(sub)
    add_tasks_parsers(sub)  # tasks, validity
    _add_mjcf_parser(sub)
    add_bench_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``comat`` console script."""
    broken = plugin_error() or learner_plugin_error()  # a bad COMAT_TASKS / COMAT_LEARNERS entry: one line,
    # before --help or any command
    if broken:
        print(f"comat: error: {broken}", file=sys.stderr)
        return 2
    args = build_parser().parse_args(argv)  # before torch loads, as _single_thread must be
    # A training announces itself before it looks for others (the runner registers it fully
    # later), so two runs started together see each other and neither spins (comat/machine.py).
    early = RunRegistry(getattr(args, "out", None) or "", 0) if args.command == "train" else None
    if early is not None:
        early.announce()
    _single_thread()
    try:
        if getattr(args, "out", None) == "":  # an empty path would write into the current folder
            raise ValueError("--out must be a file or folder path, got '' (empty)")
        return int(args.func(args) or 0)
    except (ValueError, TypeError, FileNotFoundError, FileExistsError) as exc:
        print(f"comat {args.command}: error: {exc}", file=sys.stderr)
        return 2
    finally:
        if early is not None:
            early.path.unlink(missing_ok=True)


if __name__ == "__main__":
    sys.exit(main())
