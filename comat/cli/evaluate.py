"""``comat eval``, ``probe``, ``report`` and ``sweep``: a trained policy measured, and runs brought together.

Handlers import their floors when they run, so ``comat --help`` loads neither torch nor MuJoCo.
"""

from __future__ import annotations

import argparse
import math
import os
import sys

from comat.cli.args import (
    TASKS,
    TIERS,
    add_force,
    add_policy,
    add_reality,
    add_reality_sweep,
    add_seed,
    add_task,
    add_teams,
    add_tier,
)
from comat.config import LOOPS
from comat.learners import learner_names
from comat.team import COALITION_SETS

__all__ = ["add_evaluate_parsers"]


def _cmd_eval(args: argparse.Namespace) -> int:
    from pathlib import Path

    from comat.cli.args import parse_teams, reality_arg, resolve_policy_arg
    from comat.eval import REFERENCES, evaluate_policies, print_table, result_files, write_results

    reality = reality_arg(args.reality)
    if args.episodes < 1:  # before the header line, so a bad value prints the error alone
        raise ValueError(f"episodes must be an integer >= 1 (per coalition), got {args.episodes}")
    pol = resolve_policy_arg(args.policy, args.task)
    out = Path(args.out) if args.out else pol.default_out
    named = parse_teams(args.teams, pol.task)
    tier = args.tier or pol.tier
    level = Path(reality).stem if reality.endswith((".yaml", ".yml")) else reality  # a profile: its file's name
    stem = f"evaluation_{tier}" + ("" if level == "off" else f"_{level}")  # never over an off evaluation
    stem += "" if args.loop == "comat" else f"_{args.loop}"  # nor over comat's own loop's
    if pol.checkpoint is None:  # a reference policy: it, or with the other references next to it
        refs = (pol.name,) if args.no_references else REFERENCES
    else:
        refs = () if args.no_references else REFERENCES
    # what every evaluation plays: the policy, its task, the named sets, episodes per coalition, tier, seed
    played = (pol.checkpoint, pol.task, named, args.episodes, tier, args.seed)
    what = f"{pol.label} on {pol.task}, {', '.join(n for n, _ in named)} coalitions, {args.episodes} episode(s) per "
    what += f"coalition, {tier} tier"
    if args.reality_sweep:
        refs = refs if pol.checkpoint is None else (() if args.no_references else ("heuristic",))
        return _eval_reality_sweep(args, played, what, out, refs, reality)
    from comat.config import SafetyConfig

    safety = None if args.loop == "comat" else SafetyConfig(loop=args.loop)
    return _write_evaluation(
        args,
        out,
        result_files(stem),
        f"{what}, reality {reality}, loop {args.loop}",
        lambda progress: evaluate_policies(*played, references=refs, progress=progress, reality=reality, safety=safety),
        print_table,
        lambda result: write_results(result, out, stem),
    )


def _write_evaluation(args: argparse.Namespace, out, names: list[str], what: str, run, show, write) -> int:
    """One evaluation into ``out`` (:func:`comat.files.new_outputs` of ``names``): says ``what`` plays
    on stderr, ``run(progress)``s it, ``show``s the result, ``write``s its files and names them."""
    from comat.files import new_outputs

    with new_outputs(out, names, force=args.force):
        print(f"comat eval: {what}", file=sys.stderr)
        result = run(lambda m: print(m, file=sys.stderr))
        show(result)
        paths = write(result)
    for path in paths:
        print(f"wrote {path}")
    return 0


def _eval_reality_sweep(args: argparse.Namespace, played: tuple, what: str, out, refs: tuple, base: str) -> int:
    """``comat eval --reality-sweep``: run, print, write ``evaluation_<tier>_sweep_<component>``."""
    from comat.eval import print_sweep, run_reality_sweep, sweep_files, sweep_values, write_sweep

    component = args.reality_sweep
    values = sweep_values(component, args.sweep_values, base)  # every value checked before the first episode
    stem = f"evaluation_{played[4]}_sweep_{component}"
    return _write_evaluation(
        args,
        out,
        sweep_files(stem),
        f"{what}, {component} at {values} (others at {base})",
        lambda progress: run_reality_sweep(*played, component, values, base, refs, progress=progress),
        print_sweep,
        lambda sweep: write_sweep(sweep, out, stem),
    )


def _cmd_probe(args: argparse.Namespace) -> int:
    from pathlib import Path

    from comat.cli.args import resolve_policy_arg
    from comat.eval import print_probe, probe_checkpoint, write_probe
    from comat.files import new_outputs

    pol = resolve_policy_arg(
        args.policy,
        None,
        references=(),
        need_checkpoint="comat probe reads the learner's value estimates (critic, mixer)",
    )
    out = Path(args.out) if args.out else pol.default_out
    with new_outputs(out, ["probe.json"], force=args.force):
        print(f"comat probe: {pol.checkpoint}", file=sys.stderr)
        result = probe_checkpoint(pol.checkpoint, seed=args.seed, num_envs=args.envs)
        print_probe(result)
        path = write_probe(result, out)
    print(f"wrote {path}")
    return 0


def _cmd_report(args: argparse.Namespace) -> int:
    if args.format == "marl-eval":
        return _report_marl_eval(args)
    from comat.eval import REPORT_FILES, ROBUSTNESS_FILES, SETS, make_report
    from comat.files import new_outputs

    with new_outputs(args.out, REPORT_FILES + ROBUSTNESS_FILES, force=args.force) as out:
        result = make_report(args.runs, out, args.tier)
    print(f"comat report: {result['runs']} runs ({', '.join(f'{k}: {v}' for k, v in result['groups'].items())})")
    print((out / "table1.md").read_text())
    for row in result["generalization"]:
        if not row["seeds"]:
            continue  # no runs of this algorithm on this task (yet)
        line = f"  {row['algo']:<6}{row['task']:<4}"
        for split in SETS:
            if not math.isnan(row.get(f"{split}_progress", math.nan)):
                line += f" {split} progress {100 * row[f'{split}_progress']:.0f}%"
        for split in SETS[1:]:
            value = row.get(f"{split}_retention", math.nan)
            if not math.isnan(value):
                line += f", {split}/train retention {100 * value:.0f}%"
        print(line)
    for name in result["files"]:
        print(f"wrote {out / name}")
    return 0


def _report_marl_eval(args: argparse.Namespace) -> int:
    from comat.eval import marl_eval_name, write_marl_eval
    from comat.files import new_outputs

    with new_outputs(args.out, [marl_eval_name(args.absolute_set)], force=args.force) as out:
        path, data = write_marl_eval(args.runs, out, args.tier, args.absolute_set)
    for env, tasks in data.items():
        for task, algos in tasks.items():
            for algo, runs in algos.items():
                steps = len(next(iter(runs.values()))) - 1
                print(f"  {env} {task} {algo}: {len(runs)} seed(s), {steps} step(s) + absolute_metrics")
    print(f"absolute_metrics: the final evaluation on {args.absolute_set}, one value per episode")
    print(f"wrote {path} (marl-eval's raw JSON: marl_eval.utils.data_processing_utils.data_process_pipeline reads it)")
    return 0


_SWEEP_FLAGS = ("algos", "tasks", "seeds", "preset", "steps", "tier", "eval_tiers", "eval_sets", "episodes", "device")


def _sweep_given(args: argparse.Namespace) -> dict:
    """The sweep settings given on the command line (a recorded sweep is checked against them)."""
    given = {k: getattr(args, k) for k in _SWEEP_FLAGS if getattr(args, k) is not None}
    if args.no_eval:
        given["eval_sets"] = []
    if args.overrides:
        given["overrides"] = list(args.overrides)
    if args.retries is not None:
        given["max_failures"] = args.retries
    return given


def _print_sweep_status(args: argparse.Namespace) -> int:
    from pathlib import Path

    from comat.eval import RECORD, prepare_sweep, sweep_status

    if not Path(args.out).is_dir():
        raise FileNotFoundError(
            f"--out {args.out!r} does not exist: no sweep has run there "
            f"(start it with the same command without --status)"
        )
    record, _ = prepare_sweep(args.out, _sweep_given(args))
    if not (Path(args.out) / RECORD).is_file():
        print(f"(no {RECORD} in {args.out}, a sweep from before sweeps kept a record: the grid of these flags)")
    rows = sweep_status(record["root"], record)
    print(f"{'job':<18}{'state':<8}{'env steps':>22}{'env-steps/s':>13}{'time left':>11}")
    for r in rows:
        rate = "-" if r["env_steps_per_s"] is None else f"{r['env_steps_per_s']:.0f}"
        minutes = None if r["hours_left"] is None else round(60 * r["hours_left"])
        left = "?" if minutes is None else f"{minutes // 60}:{minutes % 60:02d}"
        steps = f"{r['env_steps']:,} / {r['total_env_steps']:,}"
        print(f"{os.path.basename(r['folder']):<18}{r['state']:<8}{steps:>22}{rate:>13}{left:>11}")
    known = [r["hours_left"] for r in rows if r["hours_left"] is not None]
    jobs = args.jobs or os.cpu_count() or 1
    unknown = sum(r["hours_left"] is None for r in rows)
    print(
        f"{sum(r['state'] == 'done' for r in rows)} of {len(rows)} jobs done; about {sum(known):.1f} job-hours of "
        f"training left, {sum(known) / jobs:.1f} h at {jobs} jobs at once"
        + (f" (+ {unknown} jobs with no rate yet)" if unknown else "")
    )
    return 0


def _cmd_sweep(args: argparse.Namespace) -> int:
    from comat.eval import prepare_sweep, run_sweep

    if args.status:
        return _print_sweep_status(args)
    if args.jobs is not None and args.jobs < 1:
        raise ValueError(f"--jobs must be an integer >= 1, got {args.jobs}")
    record, notes = prepare_sweep(args.out, _sweep_given(args), command=["comat", *sys.argv[1:]])
    for line in notes:
        print(f"comat sweep: {line}")
    rows = run_sweep(record, args.address, args.jobs)
    failed = [r for r in rows if "error" in r]
    for r in failed:
        print(f"comat sweep: {os.path.basename(r['folder'])} did not finish: {r['error']:.300}", file=sys.stderr)
    print(
        f"comat sweep: {len(rows) - len(failed)} of {len(rows)} jobs finished; report with: comat report "
        f"{record['root']}/*_s* --out {record['root']}/report"
    )
    return 1 if failed else 0


def add_evaluate_parsers(sub) -> None:
    # long: four commands' options (eval, probe, report, sweep), read top to bottom as --help
    """``comat eval``, ``probe``, ``report`` and ``sweep`` on the top-level sub-parsers."""
    p = sub.add_parser(
        "eval",
        help="evaluate a policy (and reference policies) on training and unseen coalitions",
        description="The paper's metrics with 95% confidence intervals for a trained policy and the "
        "reference ladder (the scripted heuristic; type_only, the same planner knowing types but not "
        "capabilities; blind, knowing neither; the best constant action; random actions), on the coalition sets "
        "(U_train, U_val, U_test, U_scale, U_size, U_cap) or teams of your own: a table on screen, "
        "evaluation_<tier>.json (the summary), .episodes.json.gz (per-episode detail) and .csv in --out (default: "
        "the checkpoint's run folder; runs/pretrained-NAME for a shipped policy); at --reality nominal or stress, "
        "evaluation_<tier>_<level>.json and .csv. The reality layer defaults to off whatever level "
        "the policy trained at. --reality-sweep COMPONENT plays at three or more values of one "
        "component instead (evaluation_<tier>_sweep_<component>.json/.csv; comat report draws them).",
    )
    add_policy(p)
    add_task(p)
    add_teams(p)
    p.add_argument("--episodes", type=int, default=1, help="episodes per coalition (default: %(default)s)")
    add_tier(p)
    add_seed(p, "evaluation seed")
    add_reality(p)
    add_reality_sweep(p)
    p.add_argument(
        "--loop",
        choices=LOOPS,
        default="comat",
        help="what turns waypoints into wheel commands: comat's filter, or the loop an export runs on the "
        "Robotarium (robotarium_v2 / robotarium_legacy: the rps generation's own barrier; shipped_v2 / "
        "shipped_legacy: comat's shipped filter); another loop writes evaluation_<tier>[_<level>]_<loop> "
        "(default: %(default)s)",
    )
    p.add_argument(
        "--no-references",
        action="store_true",
        help="skip the reference ladder's rows (a reference --policy: only its own)",
    )
    p.add_argument(
        "--out",
        default=None,
        help="output folder, created if missing (default: the checkpoint's run "
        "folder; for pretrained:NAME, runs/pretrained-NAME: nothing is written into the package; for a "
        "reference policy, runs/POLICY-TASK)",
    )
    add_force(p)
    p.set_defaults(func=_cmd_eval)

    p = sub.add_parser(
        "probe",
        help="a checkpoint's value estimates next to the rewards its policy earns",
        description="Diagnose a trained learner: for COMAT, MAT and MAPPO one training rollout "
        "(value V̂, GAE return and normalized advantage per team size, the robot-weighted mean "
        "advantage the policy loss sees); for QMIX greedy episodes (Q_tot at the start against "
        "the discounted return, the agents' action gap, the mixer's gain, greedy action shares). "
        "Both next to the bound max step reward / (1 - gamma). A table and probe.json in --out.",
    )
    add_policy(p, required=True, references=(), policy_files=False)
    p.add_argument(
        "--seed",
        type=int,
        default=None,
        help="environment and sampling seed (default: the run's own, to replay its training rollout)",
    )
    p.add_argument("--envs", type=int, default=None, help="environments (default: the run's num_envs)")
    p.add_argument(
        "--out", default=None, help="output folder, created if missing (default: the checkpoint's run folder)"
    )
    add_force(p)
    p.set_defaults(func=_cmd_probe)

    p = sub.add_parser(
        "report",
        help="Table I, Fig. 4, Fig. 5 and team-size figure from run folders",
        description="Aggregate run folders (algorithms x tasks x seeds) into the paper's Table I "
        "(markdown + CSV, next to the paper's values and the env-step budget), the generalization "
        "table (progress, retention, finished share per composition set; t-intervals over per-seed means; "
        "Welch tests of COMAT against each baseline), aggregates.csv (also the hierarchical bootstrap "
        "over seeds then coalitions, descriptive), Fig. 4 (training return "
        "vs env steps), Fig. 5 (train vs unseen) and return/progress vs team size, as PNG and PDF. "
        "Runs need `comat eval` first. --format marl-eval writes marl_eval_<set>.json instead: the raw JSON "
        "that marl-eval reads and BenchMARL writes (env comat_<tier> / task / algorithm / seed_S / step_i, "
        "absolute_metrics from the final evaluation on --absolute-set; comat.eval.marl_eval).",
    )
    p.add_argument("runs", nargs="+", help="run folders (each with config.yaml, progress.csv, evaluation_<tier>.json)")
    p.add_argument(
        "--out",
        default="runs/report",
        help="output folder, created if missing (default: %(default)s; not results/, the checkout's own)",
    )
    p.add_argument(
        "--tier", choices=TIERS, default=None, help="which evaluation to read (default: each run's training tier)"
    )
    p.add_argument(
        "--format",
        choices=("paper", "marl-eval"),
        default="paper",
        help="paper: the tables and figures above; marl-eval: marl_eval_<set>.json for marl-eval and BenchMARL's "
        "plots (default: %(default)s)",
    )
    p.add_argument(
        "--absolute-set",
        choices=COALITION_SETS,
        default="train",
        help="--format marl-eval: the composition set whose final evaluation gives absolute_metrics "
        "(default: %(default)s, the training distribution, as marl-eval's tasks are)",
    )
    add_force(p)
    p.set_defaults(func=_cmd_report)

    p = sub.add_parser(
        "sweep",
        help="train and evaluate a grid of runs as resumable Ray Tune trials",
        description="Algorithms x tasks x seeds as Ray Tune trials (a local Ray instance, or a cluster "
        "with --address), one comat run folder each under --out, next to the sweep's record "
        "(sweep.json, written at the start). A trial whose worker fails is retried and resumes from "
        "its checkpoint; running `comat sweep --out DIR` again continues the recorded sweep "
        "(finished runs are skipped, interrupted ones resume). Settings not given: the recorded "
        "sweep's, else the defaults shown.",
    )
    p.add_argument(
        "--algos",
        nargs="+",
        choices=learner_names(),
        default=None,
        help=f"learners, any of the {len(learner_names())} registered (default: comat mat mappo qmix: the paper's)",
    )
    p.add_argument(
        "--tasks",
        nargs="+",
        choices=TASKS,
        default=None,
        help=f"tasks (default: every registered one, {' '.join(TASKS)})",
    )
    p.add_argument(
        "--seeds",
        type=int,
        nargs="+",
        default=None,
        help="seeds (default: the preset's seeds; given, they replace them, and the sweep says so)",
    )
    p.add_argument("--preset", default=None, help="preset name or YAML path (default: paper)")
    p.add_argument("--steps", type=int, default=None, help="env steps per run (default: the preset's)")
    p.add_argument("--tier", choices=TIERS, default=None, help="training tier (default: the preset's)")
    p.add_argument(
        "--eval-tiers",
        nargs="+",
        choices=TIERS,
        default=None,
        help="tiers to evaluate each final policy in (default: unicycle)",
    )
    p.add_argument(
        "--eval-sets",
        nargs="+",
        choices=list(COALITION_SETS),
        default=None,
        help="coalition sets to evaluate each final policy on (default: train test; scale needs "
        "baselines with 20 slots, models.<algo>.max_robots=20)",
    )
    p.add_argument("--episodes", type=int, default=None, help="evaluation episodes per coalition (default: 1)")
    p.add_argument("--no-eval", action="store_true", help="train only")
    p.add_argument(
        "--device",
        choices=["auto", "cpu", "cuda"],
        default=None,
        help="where each job's update runs (default: auto, cuda where the cluster has GPUs: each job "
        "then reserves one)",
    )
    p.add_argument(
        "--retries",
        type=int,
        default=None,
        help="times a failed trial is retried, resuming from its checkpoint (default: 2)",
    )
    p.add_argument(
        "--jobs",
        type=int,
        default=None,
        help="trials at once (default: as many as the CPUs hold; each reserves max(env_workers, torch_threads) CPUs)",
    )
    p.add_argument(
        "--address",
        default=None,
        help="an existing Ray cluster ('auto', or HOST:PORT of its head); --out must then be on storage "
        "every node sees at the same path",
    )
    p.add_argument("--out", default="runs/sweep", help="root folder of the sweep (default: %(default)s)")
    p.add_argument(
        "--status",
        action="store_true",
        help="print where each job of the recorded sweep stands (env steps, rate, hours left) and start nothing",
    )
    p.add_argument(
        "overrides",
        nargs="*",
        metavar="KEY=VALUE",
        help="settings changed from the preset for every job (as for comat train)",
    )
    p.set_defaults(func=_cmd_sweep)
