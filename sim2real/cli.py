"""``comat export``: write a Robotarium submission folder, or check one under rps vs MuJoCo.

=========================================  ==================================================
``comat export --checkpoint CKPT --task T  export_submission: COMAT checkpoint (or ``--policy
  --team TEAM --out DIR [--seed S]``       heuristic``, the scripted policy), team (a JSON
                                           file ``{"robots": [...]}`` or ``train:K``/``test:K``,
                                           the K-th coalition of the paper's set)
``comat export --check DIR [--tier W]      check_submission: runs DIR/main.py under the installed
  [--rps PATH]``                           rps (or the one in PATH, e.g. a V2 checkout; figures
                                           off) and the MuJoCo env; prints both
=========================================  ==================================================

Wired into ``comat/cli.py`` by ``add_export_parser(sub)`` in ``build_parser``.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

__all__ = ["add_export_parser", "parse_team"]


def parse_team(value: str, task: str):
    """A TeamSpec from ``train:K`` / ``test:K`` (coalition K of the paper's set) or a JSON file."""
    from comat.envs.base import resolve_coalitions
    from comat.team import TeamSpec

    split, sep, index = value.partition(":")
    if sep and split in ("train", "test"):
        teams = resolve_coalitions(split, task)
        if not index.isdigit() or int(index) >= len(teams):
            raise ValueError(f"--team {value!r}: index must be 0..{len(teams) - 1}")
        return teams[int(index)]
    path = Path(value)
    if not path.is_file():
        raise ValueError(f"--team must be 'train:K', 'test:K' or a JSON file with {{'robots': [...]}}, got {value!r}")
    data = json.loads(path.read_text())
    return TeamSpec.from_dict({"task": task, **data})


def _cmd_export(args: argparse.Namespace) -> int:
    from sim2real.export import check_submission, export_submission

    if args.check:
        report = check_submission(args.check, tier=args.tier, rps_path=args.rps)
        rps, mj = report["rps"], report["mujoco"]
        print(rps.pop("stdout").rstrip())
        print(f"\n{'metric':<22}{'rps (' + rps['rps'] + ')':>16}{'MuJoCo (' + args.tier + ')':>18}")
        for key in ("return", "steps", "completion", "success"):
            print(f"{key:<22}{rps[key]:>16.3f}{mj[key]:>18.3f}")
        errors = rps["rps_errors"]
        print(f"{'boundary errors':<22}{errors.get('boundary', float('nan')):>16}{mj['boundary_exits']:>18.0f}")
        print(f"{'collision errors':<22}{errors.get('collision', float('nan')):>16}"
              f"{mj['robotarium_collisions']:>18.0f}")
        print(f"{'actuator errors':<22}{errors.get('actuator', float('nan')):>16}{mj['actuator_errors']:>18.0f}")
        gap = report["gap"]
        print(f"gap rps - MuJoCo: completion {gap['completion_points']:+.1f} points, return {gap['return']:+.3f}")
        bad = errors.get("boundary", 0) + errors.get("collision", 0)
        return 1 if bad else 0
    if args.checkpoint is not None and args.policy == "heuristic":
        raise ValueError("comat export takes --checkpoint (a COMAT policy) or --policy heuristic, not both")
    missing = [f"--{k}" for k in ("task", "team", "out") if getattr(args, k) is None]
    if args.checkpoint is None and args.policy != "heuristic":
        missing.insert(0, "--checkpoint (or --policy heuristic)")
    if missing:
        raise ValueError(f"comat export needs {missing} (or --check DIR)")
    team = parse_team(args.team, args.task)
    policy = "heuristic" if args.policy == "heuristic" else args.checkpoint
    out = export_submission(policy, args.task, team, args.out, seed=args.seed)
    print(f"wrote {out}: " + ", ".join(sorted(p.name for p in out.iterdir())))
    return 0


def add_export_parser(subparsers) -> argparse.ArgumentParser:
    """Add the ``export`` command to ``subparsers`` (of ``comat``'s parser)."""
    p = subparsers.add_parser("export", help="write a Robotarium submission folder, or check one under rps",
                              description="Export a COMAT checkpoint (or the scripted policy) as a flat Robotarium "
                              "submission (main.py, runtime.py, task_logic.py, submission_config.py, weights.npy), "
                              "or --check an exported folder: run it under rps and in MuJoCo and compare.")
    p.add_argument("--checkpoint", help="COMAT checkpoint.pt")
    p.add_argument("--policy", choices=["checkpoint", "heuristic"], default="checkpoint",
                   help="'heuristic': the scripted policy (reads the task state; for checking a deployment "
                   "end to end) instead of --checkpoint (default: %(default)s)")
    p.add_argument("--task", choices=["pcp", "hmt"])
    p.add_argument("--team", help="'train:K' / 'test:K' (coalition K of the paper's set) or a JSON team file")
    p.add_argument("--out", help="folder to create (must not exist)")
    p.add_argument("--seed", type=int, default=0, help="seed of the start poses and prey (default: %(default)s)")
    p.add_argument("--check", metavar="DIR", help="check an exported folder instead of exporting")
    p.add_argument("--tier", choices=["wheels", "unicycle"], default="wheels",
                   help="MuJoCo tier of --check's comparison (default: %(default)s)")
    p.add_argument("--rps", metavar="PATH", help="--check against the rps package in PATH (e.g. a checkout of "
                   "robotarium/robotarium_python_simulator, the 2026 V2) instead of the installed one")
    p.set_defaults(func=_cmd_export)
    return p
