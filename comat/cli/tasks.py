"""``comat tasks`` (the registered tasks and their measured families) and ``comat validity`` (the
reference ladder on every set of every task, and the families: :mod:`comat.eval.validity`)."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from comat.cli.args import TASKS, TIERS, add_force, int_at_least
from comat.config import REFERENCE_TIER

__all__ = ["add_tasks_parsers", "recorded_families"]

FAMILIES_FILE = Path(__file__).resolve().parent.parent / "data" / "validity.json"
"""The families measured by the last ``comat validity --record`` (package data: ``comat tasks`` reads it)."""


def recorded_families(path: Path = FAMILIES_FILE) -> dict[str, dict]:
    """Task name -> {"env_id", "capability", "size", "seed"} as last recorded; {} when none is."""
    if not path.is_file():
        return {}
    data = json.loads(path.read_text())
    return {
        name: {
            "env_id": s.get("env_id", ""),
            "capability": bool(s["families"]["capability"][0]),
            "size": bool(s["families"]["size"][0]),
            "seed": s["seed"],
        }
        for name, s in data["tasks"].items()
    }


def _family_text(env_id: str, measured: dict | None) -> str:
    if measured is None or measured["env_id"] != env_id:
        return "families: not measured for this version (comat validity)"
    names = [f for f in ("capability", "size") if measured[f]]
    return f"families (comat validity, seed {measured['seed']}): {', '.join(names) if names else 'none: a demo'}"


def _cmd_tasks(args: argparse.Namespace) -> int:
    from comat.envs.registry import env_ids, make_task
    from comat.tasks import task_entry
    from comat.team import CAPABILITY_RANGES, SIZES, TASK_TYPES

    measured = recorded_families()
    for env_id in env_ids():
        task, _ = make_task(env_id, {})
        kinds = TASK_TYPES[task.name]
        print(
            f"{task.name} ({env_id}): {task_entry(task.name).title}; {task.horizon} steps of "
            f"{task.ticks_per_step} ticks an episode; teams of up to {task.max_team_size()} robots "
            f"(the sets: {min(min(v) for v in SIZES.values())} to {max(max(v) for v in SIZES.values())})"
        )
        print(f"  {_family_text(env_id, measured.get(task.name))}")
        names = ", ".join(f"{c} [{lo:g}, {hi:g}]" for c, (lo, hi) in zip(kinds.capabilities, kinds.limits))
        print(f"  capabilities (physical limits): {names}")
        train = CAPABILITY_RANGES[(task.name, "train")]
        for t, kind in enumerate(kinds.types):
            ranges = ", ".join(
                f"{c} {'/'.join(f'{lo:g}-{hi:g}' for lo, hi in bands)}"
                for c, bands in zip(kinds.capabilities, train[kind])
                if any(hi > 0 for _, hi in bands)
            )
            optional = " (optional: a team may have none)" if kind in kinds.optional else ""
            print(f"  type {t} {kind!r}{optional}: U_train draws {ranges}")
    return 0


def _cmd_validity(args: argparse.Namespace) -> int:
    from comat.eval import collect, run_validity, write_summary
    from comat.files import write_atomic

    out, tier = Path(args.out), args.tier or REFERENCE_TIER
    if args.summary_only:
        data = write_summary(out, collect(out, tier), tier)
    else:
        tasks = list(args.tasks)
        folders = [out / "validity" / t for t in tasks]
        taken = [str(f) for f in folders if f.exists() and any(f.iterdir())]
        if taken and not args.force:
            raise ValueError(f"--out already holds validity results for {taken}; --force replaces them")
        out.mkdir(parents=True, exist_ok=True)
        data = run_validity(tasks, out, args.episodes, args.seed, tier, progress=lambda m: print(m, file=sys.stderr))
    for name, s in data["tasks"].items():
        fam = s["families"]
        print(f"{name}: capability {'yes' if fam['capability'][0] else 'no'} ({fam['capability'][1]})")
        print(f"{' ' * len(name)}  size {'yes' if fam['size'][0] else 'no'} ({fam['size'][1]})")
    print(f"wrote {out / 'validity.md'} and {out / 'validity.json'}")
    if args.record:
        write_atomic(FAMILIES_FILE, json.dumps(data, indent=1) + "\n")
        print(f"recorded the families for `comat tasks` in {FAMILIES_FILE}")
    return 0


def add_tasks_parsers(sub) -> None:
    """``comat tasks`` and ``comat validity`` on the top-level sub-parsers."""
    from comat.eval import VALIDITY_SEED

    p = sub.add_parser(
        "tasks",
        help="list the tasks: robot types, capability names and limits, team sizes, measured families",
        description="Every registered task: its env id, episode length, the team sizes it takes, the families "
        "`comat validity` measured it in (capability: knowing capabilities beyond the type pays on U_cap; size: "
        "solvable at unseen sizes where a composition-blind plan is not), its robot types and capability names "
        "with their physical limits and U_train's ranges.",
    )
    p.set_defaults(func=_cmd_tasks)

    p = sub.add_parser(
        "validity",
        help="the reference ladder on every set of every task, and which question each task can answer",
        description="Play the reference ladder (scripted, type_only, blind, constant, random) on all six "
        "composition sets of each task on a held-out evaluation seed, and write validity.md and validity.json "
        "into --out: per task and set each rung's progress, scripted − type_only and scripted − blind with 95 % "
        "intervals over coalitions, and the families (capability: scripted − type_only >= 10 points on U_cap, "
        "lower bound > 5; size: scripted >= 90 % and scripted − blind >= 10 on U_size and U_scale). About 5 "
        "minutes a task on one core at 5 episodes per coalition.",
    )
    p.add_argument("--tasks", nargs="+", choices=TASKS, default=TASKS, help="tasks (default: every registered one)")
    p.add_argument("--episodes", type=int_at_least(1), default=5, help="episodes per coalition (default: %(default)s)")
    p.add_argument(
        "--seed",
        type=int,
        default=VALIDITY_SEED,
        help="evaluation seed (default: %(default)s, held out: never used to design a task)",
    )
    p.add_argument(
        "--tier", choices=TIERS, default=None, help=f"dynamics tier (default: {REFERENCE_TIER}, the references' tier)"
    )
    p.add_argument("--out", default="results/sets", help="output folder (default: %(default)s)")
    p.add_argument(
        "--summary-only",
        action="store_true",
        help="play nothing: rewrite validity.md/.json from the evaluations already in --out/validity/",
    )
    p.add_argument(
        "--record",
        action="store_true",
        help="also record the families in the package (comat/data/validity.json) for `comat tasks`",
    )
    add_force(p)
    p.set_defaults(func=_cmd_validity)
