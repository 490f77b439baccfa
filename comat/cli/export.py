"""``comat export``: write a Robotarium submission folder, or check one under rps vs MuJoCo.

=========================================  ==================================================
``comat export --policy CKPT|RUN|heuristic  export_submission: a COMAT checkpoint, policy.pt or run
  --team TEAM --out DIR [--seed S]``       folder (or the scripted policy; the task is the policy's),
                                           team (``train:K``/``test:K``/``scale:K``, the K-th
                                           coalition of that set, or a JSON/YAML team file)
``comat export --check DIR… [--tier W]     check_submission: runs DIR/main.py under the installed
  [--rps PATH] [--reality L|PROFILE]       rps (or the one in PATH, e.g. a V2 checkout; figures
  [--drive rps|unicycle|wheels]            off) and the MuJoCo env; prints both (several folders:
  [--repeats K]``                          a line each and the means, the sim-to-sim gap); with
                                           --reality, the reality layer around get_poses and
                                           set_velocities, judged on true poses, next to comat's
                                           own loop at that level
=========================================  ==================================================

Wired into ``comat/cli.py`` by ``add_export_parser(sub)`` in ``build_parser``.
"""

from __future__ import annotations

import argparse
import runpy
from pathlib import Path

__all__ = ["add_export_parser", "load_start_poses", "parse_team"]


def parse_team(value: str, task: str):
    """A TeamSpec from ``train:K`` / ``test:K`` / ``scale:K`` (coalition K of that set) or a JSON/YAML file
    (:func:`comat.cli.args.parse_team`, the grammar every command shares)."""
    from comat.cli.args import parse_team as parse

    return parse(value, task)


def _print_check(report: dict, tier: str) -> None:
    rps, mj = report["rps"], report["mujoco"]
    # rps's own lines (its duration estimate, its verdict), without the runtime's result line, which
    # is the table below
    printed = [line for line in rps.pop("stdout").rstrip().splitlines() if not line.startswith("COMAT_RESULT")]
    if any(line.strip() for line in printed):
        print("main.py under rps printed:\n" + "\n".join("  " + line for line in printed))
    print(f"\n{'metric':<22}{'rps (' + rps['rps'] + ')':>16}{'MuJoCo (' + tier + ')':>18}")
    for key in ("return", "steps", "progress", "finished"):
        print(f"{key:<22}{rps[key]:>16.3f}{mj[key]:>18.3f}")
    errors = rps["rps_errors"]
    print(f"{'boundary errors':<22}{errors.get('boundary', float('nan')):>16}{mj['boundary_exits']:>18.0f}")
    print(f"{'collision errors':<22}{errors.get('collision', float('nan')):>16}{mj['robotarium_collisions']:>18.0f}")
    print(f"{'actuator errors':<22}{errors.get('actuator', float('nan')):>16}{mj['actuator_errors']:>18.0f}")
    gap = report["gap"]
    print(
        f"gap rps - MuJoCo: progress {gap['progress_points']:+.1f} points, return {gap['return']:+.3f} "
        "(the MuJoCo column is comat's own loop with the same policy and team, docs/export.md)"
    )
    if "run_log" in rps:  # the run's own log, as the Robotarium returns it
        print(_log_line(rps["run_log"]))


def _log_line(folder: str) -> str:
    """Where a checked run's log is, how large, and its size per robot-minute."""
    from comat.runlog import LOG_FILE, META_FILE, bytes_per_robot_minute, read_run_log

    log = read_run_log(folder)
    size = sum((Path(folder) / f).stat().st_size for f in (LOG_FILE, META_FILE))
    minutes = len(log.t) * 0.033 / 60
    return (
        f"run log: {folder} ({size / 1e3:.0f} kB for {len(log.t)} iterations of {log.n} robots: "
        f"{size / max(minutes * log.n, 1e-9) / 1e3:.0f} kB per robot-minute; "
        f"{bytes_per_robot_minute() / 1e3:.0f} kB plus the metadata)"
    )


def _print_checks(folders: list[str], reports: list[dict], tier: str) -> None:
    """One line per folder, then the means: the sim-to-sim gap over several teams."""
    print(
        f"{'folder':<28}{'robots':>7}{'rps errors b/c/a':>18}{'progress rps / MuJoCo':>26}"
        f"{'return rps / MuJoCo':>24}{'steps':>12}"
    )
    for folder, r in zip(folders, reports):
        rps, mj, e = r["rps"], r["mujoco"], r["rps"]["rps_errors"]
        errors = f"{e.get('boundary', '-')}/{e.get('collision', '-')}/{e.get('actuator', '-')}"
        print(
            f"{Path(folder).name[:27]:<28}{rps['robots']:>7}{errors:>18}"
            f"{rps['progress']:>15.3f} / {mj['progress']:<8.3f}"
            f"{rps['return']:>13.2f} / {mj['return']:<8.2f}{rps['steps']:>5.0f} / {mj['steps']:<4.0f}"
        )
    mean = {}
    for side in ("rps", "mujoco"):
        for k in ("progress", "return", "steps"):
            mean[side, k] = sum(r[side][k] for r in reports) / len(reports)
    print(
        f"mean over {len(reports)} folders (rps {reports[0]['rps']['rps']}, MuJoCo {tier}): progress "
        f"{100 * mean['rps', 'progress']:.1f} % vs {100 * mean['mujoco', 'progress']:.1f} % "
        f"(gap {100 * (mean['rps', 'progress'] - mean['mujoco', 'progress']):+.1f} points), return "
        f"{mean['rps', 'return']:.2f} vs {mean['mujoco', 'return']:.2f}, steps {mean['rps', 'steps']:.1f} vs "
        f"{mean['mujoco', 'steps']:.1f}"
    )


def _print_reality(folders: list[str], reports: list[dict], tier: str) -> int:
    """The deployed loop under the reality layer, per folder, next to comat's loop at the same
    level; the collisions found (each named: folder, run, robots, iteration). Returns their count."""
    first = reports[0]["rps"]["reality"]
    print(
        f"\ndeployed loop under the reality layer ({first['level']}, robots moved by {first['drive']}), judged on "
        f"true poses; comat's own loop in MuJoCo ({tier}) at the same level:"
    )
    print(
        f"{'folder':<28}{'filter':>11}{'runs':>6}{'collision runs':>16}{'pair-iter.':>11}{'contacts':>9}"
        f"{'closest (m)':>12}{'progress deployed / comat':>28}"
    )
    hits = 0
    for folder, r in zip(folders, reports):
        rec, rps, mj = r["rps"]["reality"], r["rps"], r["mujoco"]
        contacts = "-" if rec["mujoco_contact_ticks"] is None else str(rec["mujoco_contact_ticks"])
        closest = rec["min_offset_centre_distance_m"]
        print(
            f"{Path(folder).name[:27]:<28}{rps.get('filter', 'robotarium'):>11}{rec['runs']:>6}"
            f"{rec['runs_with_collisions']:>16}{rec['collision_pair_iterations']:>11}{contacts:>9}"
            f"{closest if closest is not None else float('nan'):>12.3f}"
            f"{100 * rps['progress']:>18.1f} / {100 * mj['progress']:<6.1f}"
        )
        hits += rec["runs_with_collisions"] + bool(rec["mujoco_contact_ticks"])
        if rec["first_collision"]:
            c = rec["first_collision"]
            print(
                f"  COLLISION in {folder}: run {c['run']} (layer seed {c['run']}), robots {c['robots'][0]} and "
                f"{c['robots'][1]} at iteration {c['iteration']} (offset centres {c['distance_m']:.3f} m <= "
                f"{0.135} m)"
            )
    return hits


def _print_repeats(folders: list[str], reports: list[dict], repeats: int) -> None:
    """What the rps figures above rest on: one run (and whether that is one sample), or K runs'
    spread per folder."""
    generation = reports[0]["rps"]["rps"]
    if repeats == 1:
        if generation == "v2":
            print(
                "rps figures: one run per folder. V2 starts each run from random charger places, so it is one "
                "random sample; --repeats K gives the mean and spread of K runs"
            )
        return
    for folder, report in zip(folders, reports):
        runs = report["rps"]["runs"]
        comp = [100 * r["progress"] for r in runs]
        errors = [sum(r["rps_errors"].values()) for r in runs]
        print(
            f"{Path(folder).name}: {len(runs)} rps runs ({generation}): progress mean {sum(comp) / len(comp):.1f} %, "
            f"min {min(comp):.1f}, max {max(comp):.1f}; steps {min(r['steps'] for r in runs):.0f}-"
            f"{max(r['steps'] for r in runs):.0f}; runs with rps errors {sum(e > 0 for e in errors)}/{len(runs)}"
        )


def load_start_poses(path: str):
    """(3, N) start poses from a ``.npy`` file or a text file of 3 rows (x, y, θ; numpy.loadtxt)."""
    import numpy as np

    p = Path(path)
    if not p.is_file():
        raise ValueError(f"--start-poses must be a .npy or text file of 3 rows (x, y, θ), got {path!r} (no such file)")
    try:
        return np.load(p, allow_pickle=False) if p.suffix == ".npy" else np.loadtxt(p, ndmin=2)
    except (OSError, ValueError) as err:
        raise ValueError(
            f"--start-poses {path!r}: expected a .npy array or numeric text of 3 rows, "
            f"could not read it ({type(err).__name__}: {str(err).splitlines()[0][:120] if str(err) else ''})"
        ) from err


def _cmd_export(args: argparse.Namespace) -> int:
    # long: the command's three modes (--calibration, --check, an export) with their lazy imports and printed lines
    import sys
    import time

    from comat import constants as C
    from sim2real.calibration import check_calibration, export_calibration, is_calibration
    from sim2real.check import CheckError, check_submission
    from sim2real.export import export_submission, load_config

    if args.calibration:
        folders = export_calibration(args.calibration, args.robots)
        for f in folders:
            config = runpy.run_path(str(f / "submission_config.py"))["CONFIG"]
            print(
                f"wrote {f}: "
                + ", ".join(sorted(p.name for p in f.iterdir()))
                + f"; declare {config['duration_s']:.0f} s and {config['robots']} robots"
            )
        print(
            "upload each folder to the Robotarium, download the calib_<experiment>.npy it saves, then fit: "
            "comat calibrate calib_steps.npy calib_still.npy calib_ramp.npy calib_spin.npy --out my_robots.yaml"
        )
        return 0
    if args.check and all(is_calibration(f) for f in args.check):
        bad = 0
        for folder in args.check:
            try:
                report = check_calibration(folder, args.timeout, args.rps)
            except CheckError as err:
                raise ValueError(str(err)) from err
            rps, fit = report["rps"], report["fit"]
            bad += rps["rps_errors"].get("boundary", 0) + rps["rps_errors"].get("collision", 0)
            keys = [k for k in fit[0] if k not in ("rms_m",)]
            shown = ", ".join(f"{k} {min(r[k] for r in fit):.4g}..{max(r[k] for r in fit):.4g}" for k in keys)
            print(
                f"{folder}: {rps['experiment']} under rps ({rps['rps_generation']}), {rps['iterations']} iterations, "
                f"{rps['robots']} robots, rps errors {rps['rps_errors']}; log {rps['log']}; fit per robot: {shown}"
            )
        return 1 if bad else 0
    if args.check:
        from comat.cli.args import reality_arg

        if args.timeout <= 0:
            raise ValueError(f"--timeout must be > 0 seconds, got {args.timeout}")
        reality = reality_arg(args.reality) if args.reality is not None else None
        reports = []
        for k, folder in enumerate(args.check, 1):
            t0 = time.perf_counter()
            print(
                f"[{k}/{len(args.check)}] {folder}: running main.py under rps, then the MuJoCo episode ...",
                file=sys.stderr,
                flush=True,
            )
            try:
                reports.append(
                    check_submission(
                        folder,
                        tier=args.tier,
                        timeout_s=args.timeout,
                        rps_path=args.rps,
                        repeats=args.repeats,
                        reality=reality,
                        drive=args.drive,
                    )
                )
            except CheckError as err:
                raise ValueError(str(err)) from err
            print(
                f"[{k}/{len(args.check)}] {folder}: done in {time.perf_counter() - t0:.0f} s",
                file=sys.stderr,
                flush=True,
            )
        if len(reports) == 1:
            _print_check(reports[0], args.tier)
        else:
            _print_checks(args.check, reports, args.tier)
        _print_repeats(args.check, reports, args.repeats)
        for folder, report in zip(args.check, reports):
            for warning in report["rps"]["duration_warnings"]:
                print(f"comat export: warning: {folder}: {warning}", file=sys.stderr)
        bad = sum(
            r["rps"]["rps_errors"].get("boundary", 0) + r["rps"]["rps_errors"].get("collision", 0) for r in reports
        )
        if reality is not None:
            bad += _print_reality(args.check, reports, args.tier)
        return 1 if bad else 0
    from comat.cli.args import reality_arg, resolve_policy_arg
    from comat.learners import learner_entry, learner_names

    shipped = tuple(n for n in learner_names() if learner_entry(n).exports)
    why = "an export ships a numpy forward pass, which sim2real/runtime.py has for these learners only"
    # a --policy given is checked before the flags left out are named: a wrong path is said at once,
    # not after the user has added --team and --out
    pol = None
    if args.policy is not None:
        pol = resolve_policy_arg(args.policy, args.task, references=("heuristic",), algos=shipped, why=why)
    missing = [f"--{k}" for k in ("policy", "team", "out") if getattr(args, k) is None]
    if missing:
        raise ValueError(f"comat export needs {', '.join(missing)} (or --check DIR)")
    team = parse_team(args.team, pol.task)
    poses = None if args.start_poses is None else load_start_poses(args.start_poses)
    from comat.files import new_outputs

    # export_submission refuses an existing folder itself; this removes parents it made if it fails
    with new_outputs(Path(args.out).parent, []):
        out = export_submission(
            str(pol.checkpoint or pol.name),
            pol.task,
            team,
            args.out,
            start_poses=poses,
            seed=args.seed,
            filter_name=args.filter,
            filter_reality=reality_arg(args.filter_reality, "--filter-reality"),
        )
    config = load_config(out)
    print(f"wrote {out}: " + ", ".join(sorted(p.name for p in out.iterdir())))
    print(
        f"declare {config['duration_s']} s and {config['robots']} robots (episode up to {config['horizon_s']:.0f} s "
        f"+ start-up drive up to {config['startup_drive_s']:.0f} s, + {100 * C.DURATION_MARGIN:.0f} %, rounded up)"
    )
    return 0


def add_export_parser(subparsers) -> argparse.ArgumentParser:
    # long: the export command's options, one add_argument each, read top to bottom as its --help page
    """Add the ``export`` command to ``subparsers`` (of ``comat``'s parser)."""
    p = subparsers.add_parser(
        "export",
        help="write a Robotarium submission folder, or check one under rps",
        description="Export a COMAT checkpoint or policy.pt (or the scripted policy) as a flat "
        "Robotarium submission (main.py, runtime.py, task_logic.py, submission_config.py, "
        "weights.npy), or --check an exported folder: run it under rps and in MuJoCo and compare.",
    )
    from comat.cli.args import TIERS, add_filter, add_policy, add_seed, add_task, add_team

    add_policy(p, required=True, references=("heuristic",))  # no default: an export names what it ships
    add_task(p)
    add_team(p)
    p.add_argument(
        "--out", help="folder to create, with its parents (refused if it exists; removed again if the export fails)"
    )
    add_seed(p, "seed of the start poses and prey")
    p.add_argument(
        "--start-poses",
        metavar="FILE",
        help="start poses instead of the seed's: a .npy (3, N) array or "
        "a text file of 3 rows x, y, θ (m, m, rad); checked: inside the arena by 0.1 m, centres >= 0.4 m "
        "apart (what the Robotarium's start-up drive can reach)",
    )
    add_filter(p)
    p.add_argument(
        "--timeout",
        type=float,
        default=1800.0,
        help="--check: seconds main.py may run under rps per folder (default: %(default)s)",
    )
    p.add_argument(
        "--calibration",
        metavar="OUT",
        default=None,
        help="instead: write the four calibration experiments as Robotarium submission folders OUT/steps, "
        "OUT/still, OUT/ramp and OUT/spin (each logs commands and poses to calib_<experiment>.npy for comat "
        "calibrate; its submission_config.py says the duration to declare, the start-up drive included)",
    )
    p.add_argument(
        "--robots", type=int, default=4, help="--calibration: robots per experiment, 1-4 (default: %(default)s)"
    )
    p.add_argument(
        "--check",
        metavar="DIR",
        nargs="+",
        help="check exported folders instead of exporting (several: one line each, then the means)",
    )
    p.add_argument(
        "--tier",
        choices=TIERS,
        default="unicycle",
        help="MuJoCo tier of --check's comparison (default: %(default)s, as comat replay's twin: the presets' "
        "training tier, and the exact unicycle arc the Robotarium simulator integrates; wheels adds the motor "
        "response, tyre creep and the layer's floor friction, mass and centre-of-mass components)",
    )
    p.add_argument(
        "--rps",
        metavar="PATH",
        help="--check against the rps package in PATH (e.g. a checkout of "
        "robotarium/robotarium_python_simulator, the 2026 V2) instead of the installed one",
    )
    p.add_argument(
        "--reality",
        default=None,
        metavar="LEVEL|PROFILE",
        help="--check with the reality layer around rps's get_poses and set_velocities (off, nominal, stress "
        "or a profile.yaml of comat calibrate): the exact main.py, its filter and wheel scaling, judged on "
        "true poses (closest robots, collisions named by robots and iteration) next to comat's own loop "
        "at that level; run k has layer seed k; exit 1 on a collision (default: off, the ideal world)",
    )
    p.add_argument(
        "--drive",
        default="rps",
        metavar="{rps,unicycle,wheels}",
        help="--check --reality: what moves the robots: rps's own integration, or comat's MuJoCo world "
        "(contacts counted) in that tier (default: %(default)s)",
    )
    p.add_argument(
        "--repeats",
        type=int,
        default=1,
        metavar="K",
        help="--check: run main.py under rps K times and report the means and the spread (V2 drives the "
        "robots from random charger places first, so one V2 run is one random sample; default: "
        "%(default)s)",
    )
    p.set_defaults(func=_cmd_export)
    return p
