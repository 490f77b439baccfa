"""``comat campaign``: one policy on the Robotarium across team sizes × runs, and what comes back.

==============================================  =============================================
``comat campaign --policy P [--task T]          :func:`comat.eval.campaign.make_campaign`: a
  --sizes 4,8,12,20 --runs N --out DIR          submission folder per (size, run), manifest.json
  [--sets test,scale] [--seed S]``              and manifest.md; prints what to declare
``comat campaign --analyze RETURNED             :func:`comat.eval.campaign_returns.analyze_campaign`:
  --manifest DIR/manifest.json --out OUT        each run beside its twin, the paired table per
  [--reality L|PROFILE] [--tier] [--draws]``    size, the failure list, the Rerun files
``comat campaign --stand-in DIR/manifest.json   :func:`comat.eval.campaign.stand_in_returns`:
  --out RETURNED [--reality] [--drive]          every folder's main.py under rps, returned as
  [--max-steps K] [--rps PATH]``                the Robotarium returns it (a rehearsal)
==============================================  =============================================

Handlers import their floors when they run: ``comat --help`` loads neither torch nor Rerun.
"""

from __future__ import annotations

import argparse
import sys

from comat.cli.args import TIERS, add_filter, add_policy, add_reality, add_seed, add_task

__all__ = ["add_campaign_parser"]


def _make(args: argparse.Namespace) -> int:
    from comat.cli.args import reality_arg, resolve_policy_arg
    from comat.eval import declarations, make_campaign, parse_sets, parse_sizes, plan_teams
    from comat.learners import learner_entry, learner_names

    missing = [f"--{k}" for k in ("policy", "sizes", "runs", "out") if getattr(args, k) is None]
    if missing:
        raise ValueError(f"comat campaign needs {', '.join(missing)} (or --analyze RETURNED, or --stand-in MANIFEST)")
    sizes, sets = parse_sizes(args.sizes), parse_sets(args.sets)  # one-line errors before the policy loads
    shipped = tuple(n for n in learner_names() if learner_entry(n).exports)
    why = "an export ships a numpy forward pass, which sim2real/runtime.py has for these learners only"
    pol = resolve_policy_arg(args.policy, args.task, references=("heuristic",), algos=shipped, why=why)
    plan_teams(pol.task, sizes, args.runs, sets, args.seed)  # a size no set has: one line, before the announcement
    filter_reality = reality_arg(args.filter_reality, "--filter-reality")
    print(
        f"comat campaign: {pol.label} on {pol.task}, sizes {sizes} × {args.runs} runs, teams from {sets}, "
        f"seed {args.seed} ...",
        file=sys.stderr,
        flush=True,
    )
    manifest = make_campaign(
        str(pol.checkpoint or pol.name),
        pol.task,
        sizes,
        args.runs,
        args.out,
        sets=sets,
        seed=args.seed,
        policy_label=pol.shipped or (pol.name if pol.checkpoint is None else str(pol.checkpoint)),
        filter_name=args.filter,
        filter_reality=filter_reality,
    )
    for line in declarations(manifest):
        print(line)
    total = sum(e["duration_s"] for e in manifest["folders"])
    print(
        f"wrote {args.out}: {len(manifest['folders'])} submission folders, manifest.json and manifest.md; "
        f"{total} s ({total / 60:.0f} min) declared in all"
    )
    return 0


def _analyze(args: argparse.Namespace) -> int:
    from comat.cli.args import reality_arg
    from comat.eval import analyze_campaign
    from comat.viz.viewer import viewer_hint

    if args.manifest is None or args.out is None:
        raise ValueError("comat campaign --analyze RETURNED needs --manifest DIR/manifest.json and --out OUT")
    reality = reality_arg(args.reality)
    profiles = [reality_arg(p, "--profiles") for p in args.profiles]
    result = analyze_campaign(
        args.analyze,
        args.manifest,
        args.out,
        reality=reality,
        tier=args.tier or "unicycle",
        draws=args.draws,
        profiles=profiles,
        progress=lambda line: print(f"comat campaign: {line}", file=sys.stderr, flush=True),
    )
    print(result["markdown"])
    print(f"wrote {result['out']}: campaign.md, sizes.csv, runs.csv, failures.csv, runs/<folder>/replay.rrd")
    first = next((r for r in result["runs"] if r["log"] is not None), None)
    if first is not None:
        print(viewer_hint(result["out"] / "runs" / first["entry"]["folder"] / "replay.rrd"))
    return 0


def _stand_in(args: argparse.Namespace) -> int:
    from comat.cli.args import reality_arg
    from comat.eval import stand_in_returns
    from sim2real.check import CheckError

    if args.out is None:
        raise ValueError("comat campaign --stand-in MANIFEST needs --out RETURNED (the folder to create)")
    if args.max_steps is not None and args.max_steps < 1:
        raise ValueError(f"--max-steps must be an integer >= 1, got {args.max_steps}")
    reality = reality_arg(args.reality)
    try:
        folders = stand_in_returns(
            args.stand_in,
            args.out,
            reality=None if reality == "off" else reality,
            drive=args.drive,
            max_steps=args.max_steps,
            rps_path=args.rps,
        )
    except CheckError as err:  # a main.py that failed under rps: one line, as export --check says it
        raise ValueError(str(err)) from err
    print(f"wrote {args.out}: what the Robotarium returns, for {len(folders)} experiments run under rps")
    return 0


def _cmd(args: argparse.Namespace) -> int:
    if args.analyze is not None and args.stand_in is not None:
        raise ValueError("--analyze and --stand-in are two modes: give one")
    if args.analyze is not None:
        return _analyze(args)
    if args.stand_in is not None:
        return _stand_in(args)
    return _make(args)


def add_campaign_parser(subparsers) -> argparse.ArgumentParser:
    # long: the campaign command's options, one add_argument each, read as its --help page
    """``comat campaign`` on the top-level sub-parsers."""
    p = subparsers.add_parser(
        "campaign",
        help="a hardware campaign: one policy across team sizes × runs as Robotarium folders, and --analyze "
        "what comes back",
        description="Writes one Robotarium submission folder per (team size, run) for one policy (teams of each "
        "size drawn from --sets), a manifest.json and manifest.md, and prints the duration and robots to declare "
        "for each. --analyze reads what the Robotarium returned (a subfolder per experiment: log.txt and the run "
        "log), replays each run beside its twin, and writes the paired sim/real table per team size with "
        "t-intervals over runs, a failure list (missing files, timeouts, crashes, collisions, boundary errors, "
        "freezes) and a Rerun file per run. --stand-in runs every folder under rps and writes what the Robotarium "
        "would return (docs/campaign.md).",
    )
    add_policy(p, required=True, references=("heuristic",))  # no default: a campaign names what it ships
    add_task(p)
    p.add_argument("--sizes", default=None, metavar="N,N,…", help="team sizes, e.g. 4,8,12,20")
    p.add_argument("--runs", type=int, default=None, metavar="N", help="runs per team size (the replicated unit)")
    p.add_argument(
        "--sets",
        default="test,scale",
        metavar="SET,SET",
        help="composition sets the teams come from, by name or as U_test, U_scale, … (default: %(default)s)",
    )
    add_seed(p, "seed of the team order, start poses and task layouts")
    p.add_argument(
        "--out",
        default=None,
        help="the folder to create: the campaign (its folders and manifest), --analyze's tables, or --stand-in's "
        "returned folder (refused if it exists; nothing is left if the command fails)",
    )
    add_filter(p)
    p.add_argument(
        "--analyze",
        default=None,
        metavar="RETURNED",
        help="instead: read the folder of what the Robotarium returned (a subfolder per manifest folder)",
    )
    p.add_argument("--manifest", default=None, metavar="FILE", help="--analyze: the campaign's manifest.json")
    add_reality(
        p,
        "--analyze: the level or calibrated profile the twins play at and whose plant is scored; "
        "--stand-in: the layer the runs play in (default: %(default)s)",
    )
    p.add_argument(
        "--tier",
        choices=TIERS,
        default=None,
        help="--analyze: the twins' dynamics tier (default: unicycle, as comat replay)",
    )
    p.add_argument(
        "--profiles",
        nargs="+",
        default=[],
        metavar="L|PROFILE.yaml",
        help="--analyze: also score these levels' or profiles' plants on every run's log (k-step score per size, "
        "beside --reality's: which predicts the robots best)",
    )
    p.add_argument(
        "--draws",
        type=int,
        default=8,
        help="--analyze: draws of the profile's randomness per k-step start (default: %(default)s; one at off)",
    )
    p.add_argument(
        "--stand-in",
        default=None,
        metavar="MANIFEST",
        help="instead: run every folder of this campaign under rps (at --reality) and write what the Robotarium "
        "returns into --out: a rehearsal of --analyze",
    )
    p.add_argument(
        "--drive",
        default="rps",
        choices=("rps", "unicycle", "wheels"),
        help="--stand-in --reality: what moves the robots (as comat export --check; default: %(default)s)",
    )
    p.add_argument(
        "--max-steps", type=int, default=None, metavar="K", help="--stand-in: stop each run after K env steps"
    )
    p.add_argument("--rps", default=None, metavar="PATH", help="--stand-in: the rps package in PATH (e.g. V2)")
    p.set_defaults(func=_cmd)
    return p
