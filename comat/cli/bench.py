"""``comat bench``: performance and fidelity benchmarks, each writing JSON and printing a table.

``sim``, ``env``, ``learn``, ``soak``, ``fidelity``, ``safety`` and ``viz``; handlers import their
benchmark when they run.
"""

from __future__ import annotations

import argparse
import time

from comat.bench import (
    COMAT_VARIANTS,
    CROSSING_NAMES,
    DEFAULT_LOOPS,
    OVERLAP_CHOICES,
    SCENARIO_NAMES,
    WIDE_SLOTS,
    learn_rows,
    run_safety_bench,
)
from comat.cli.args import TASKS, TIERS, int_at_least
from comat.cli.rollout import add_viz_bench_parser
from comat.config import LOOPS
from comat.reality.config import REALITY_LEVELS
from comat.team import COALITION_SETS

__all__ = ["add_bench_parser"]


def _cmd_bench(args: argparse.Namespace) -> int:
    if args.what == "sim":
        from comat.bench import run_sim_bench

        sizes = tuple(args.sizes)
        t0 = time.perf_counter()
        print(
            f"comat bench sim: N={sizes}, B={tuple(args.batches)}, tiers={tuple(args.tiers)}, {args.ticks} ticks each"
        )
        run_sim_bench(sizes, tuple(args.batches), tuple(args.tiers), args.ticks, args.rps_ticks, args.out)
        print(f"done in {time.perf_counter() - t0:.0f} s")
        return 0
    if args.what == "env" and args.rollout:
        from comat.bench import run_rollout_bench

        run_rollout_bench(
            args.tasks[0],
            args.tiers[-1],
            args.rollout_batch,
            2,
            max(args.steps // 2, 4),
            args.out or "benchmarks/results/env_rollout.json",
        )
        return 0
    if args.what == "env":
        from comat.bench import run_env_bench

        t0 = time.perf_counter()
        run_env_bench(
            tuple(args.tasks),
            tuple(args.tiers),
            tuple(args.sizes),
            tuple(args.batches),
            args.steps,
            args.out or "benchmarks/results/env.json",
        )
        print(f"done in {time.perf_counter() - t0:.0f} s")
        return 0
    if args.what == "learn":
        from comat.bench import run_learn_bench

        t0 = time.perf_counter()
        print(
            f"comat bench learn: decode (COMAT, MAT, 8 robots), training {tuple(args.algos)} on "
            f"{tuple(args.tasks)} with env workers {tuple(args.workers)}, {args.iterations} iterations each; "
            f"the PPO updates alone, taking turns, {args.update_rounds} rounds"
        )
        run_learn_bench(
            tuple(args.algos),
            tuple(args.workers),
            args.iterations,
            tuple(args.batches),
            args.out,
            tasks=tuple(args.tasks),
            overlap=args.overlap,
            update_rounds=args.update_rounds,
        )
        print(f"done in {time.perf_counter() - t0:.0f} s")
        return 0
    if args.what == "soak":
        from comat.bench import run_soak

        result = run_soak(args.episodes, args.wheels_share, args.seed, args.out, sets=args.sets)
        return 0 if all(c["pass"] for c in result["checks"].values()) else 1
    if args.what == "fidelity":
        from comat.bench import run_fidelity_bench

        run_fidelity_bench(seeds=args.seeds, out=args.out)
        return 0
    raise AssertionError(args.what)


def _cmd_safety(args: argparse.Namespace) -> int:
    if args.mismatch:
        from comat.bench import MISMATCH_SCENARIOS, run_mismatch

        names = tuple(args.scenarios) if args.scenarios else MISMATCH_SCENARIOS
        loops = tuple(args.loops) if args.loops != list(DEFAULT_LOOPS) else ("comat",)
        run_mismatch(args.episodes, args.seed, args.out, names, loops, args.tiers[0])
        return 0
    result = run_safety_bench(
        tuple(args.reality),
        tuple(args.tiers),
        args.episodes,
        args.seed,
        args.out,
        tuple(args.scenarios) if args.scenarios else None,
        tuple(args.loops),
    )
    return 0 if all(c["pass"] for c in result["checks"].values()) else 1


def add_bench_parser(sub) -> None:
    # long: every benchmark's options, one add_argument each, read top to bottom as the --help pages
    """``comat bench`` and its benchmarks on the top-level sub-parsers."""
    p = sub.add_parser("bench", help="benchmarks (JSON + table)", description="Performance and fidelity benchmarks.")
    bsub = p.add_subparsers(dest="what", required=True, metavar="WHAT")
    b = bsub.add_parser(
        "sim",
        help="µs per control tick vs team size, batch and tier; vs the Robotarium simulator",
        description="Time one control tick (physics + barrier filter + the rest) and compare "
        "with the Robotarium simulator's own loop (PyPI rps, unicycle barrier every step).",
    )
    b.add_argument("--sizes", type=int, nargs="+", default=[2, 4, 8, 16, 32], help="team sizes (default: %(default)s)")
    b.add_argument("--batches", type=int, nargs="+", default=[1, 64], help="teams per batch (default: %(default)s)")
    b.add_argument("--tiers", nargs="+", choices=TIERS, default=["wheels", "unicycle"])
    b.add_argument("--ticks", type=int, default=100, help="measured ticks per configuration (default: %(default)s)")
    b.add_argument("--rps-ticks", type=int, default=100, help="measured Robotarium iterations (default: %(default)s)")
    b.add_argument("--out", default="benchmarks/results/sim.json", help="JSON output (default: %(default)s)")
    b.set_defaults(func=_cmd_bench)
    b = bsub.add_parser(
        "env",
        help="env-steps/s with random actions per task, tier, batch and team size",
        description="Time vector environments (safety filter at every tick) with random actions, "
        "next to the Robotarium simulator's loop per env step.",
    )
    b.add_argument("--tasks", nargs="+", choices=TASKS, default=list(TASKS), help="tasks (default: %(default)s)")
    b.add_argument("--tiers", nargs="+", choices=TIERS, default=["wheels", "unicycle"])
    b.add_argument(
        "--sizes", type=int, nargs="+", default=[2, 5, 8, 12, 16, 20], help="team sizes (default: %(default)s)"
    )
    b.add_argument(
        "--batches", type=int, nargs="+", default=[1, 64], help="environments per batch (default: %(default)s)"
    )
    b.add_argument("--steps", type=int, default=20, help="measured steps at batch 1; a quarter at larger batches")
    b.add_argument(
        "--out",
        default=None,
        help="JSON output (default: benchmarks/results/env.json; with --rollout: benchmarks/results/env_rollout.json)",
    )
    b.add_argument(
        "--rollout",
        action="store_true",
        help="instead: where a rollout step's time goes (training coalitions, --rollout-batch envs; "
        "physics, OSQP, the rest) for all of them in one process, for each half two env processes would "
        "hold, and for one env; first of --tasks, last of --tiers",
    )
    b.add_argument("--rollout-batch", type=int, default=32, help="environments for --rollout (default: %(default)s)")
    b.set_defaults(func=_cmd_bench)
    b = bsub.add_parser(
        "learn",
        help="cached vs uncached decoding; training env-steps/s per algorithm",
        description="Autoregressive decoding with cached keys/values vs a full decoder re-run per "
        "robot (COMAT, MAT, 8 robots), and end-to-end training throughput (collect + learn) per "
        "algorithm on PCP and HMT (--tasks) in the unicycle tier with the paper's settings.",
    )
    b.add_argument(
        "--algos",
        nargs="+",
        choices=learn_rows(),
        default=["comat", "comat_paper", "mat", "mappo", "qmix"],
        help="algorithms to train; comat_paper: COMAT in the paper form (eq. 2-3 literally), "
        f"to compare today's default with it in one run; {', '.join(COMAT_VARIANTS)}: COMAT with that "
        f"decision layer or one HEAT block; <learner>_{WIDE_SLOTS}: a team-sized learner with {WIDE_SLOTS} "
        "robot slots instead of 8 (default: %(default)s)",
    )
    b.add_argument(
        "--workers",
        type=int,
        nargs="+",
        default=[1, 2],
        help="environment worker processes to compare (default: %(default)s)",
    )
    b.add_argument(
        "--iterations",
        type=int,
        default=2,
        help="timed training iterations per algorithm, each 2,560 env steps (default: %(default)s)",
    )
    b.add_argument(
        "--update-rounds",
        type=int_at_least(0),
        default=5,
        help="timed rounds of each PPO learner's update alone, each round on a rollout of its own (the "
        "same teams for every learner), the learners taking turns, so that a drift of the machine's "
        "speed touches them alike; the check of COMAT's update against MAT's reads them; 0: skip "
        "(default: %(default)s)",
    )
    b.add_argument(
        "--tasks",
        nargs="+",
        choices=list(TASKS),
        default=list(TASKS),
        help="tasks to train on (HMT's step is 74 ticks against PCP's 29) (default: %(default)s)",
    )
    b.add_argument(
        "--batches", type=int, nargs="+", default=[1, 32, 256], help="decoding batch sizes (default: %(default)s)"
    )
    b.add_argument(
        "--overlap",
        choices=list(OVERLAP_CHOICES),
        default="off",
        help="time the PPO learners with ppo.overlap, the next rollout collected while the update runs "
        "(on), or both with and without it in one run (both); it gains only where cores are left over "
        "beside the env workers and the learner's threads (default: %(default)s)",
    )
    b.add_argument("--out", default="benchmarks/results/learn.json", help="JSON output (default: %(default)s)")
    b.set_defaults(func=_cmd_bench)
    b = bsub.add_parser(
        "soak",
        help="many reference-policy episodes: contacts, collisions, NaN, memory drift",
        description="Episodes of the scripted and the random policy on composition sets of both "
        "tasks (unicycle tier, a share in the wheels tier): every contact, collision, boundary exit, "
        "actuator error, NaN, filter recovery and fallback counted, and resident memory after every batch, "
        "compared over the first and the last thousand episodes. Not part of the tests: one round of 160 episodes "
        "(U_train and U_test) "
        "took 2 min on this 2-core machine (under load), so 10,000 take an hour or more.",
    )
    b.add_argument("--episodes", type=int, default=10_000, help="at least this many episodes (default: %(default)s)")
    b.add_argument(
        "--sets",
        nargs="+",
        choices=list(COALITION_SETS),
        default=["train", "test"],
        help="composition sets (default: %(default)s; scale: 10-20 robots, slower per episode)",
    )
    b.add_argument(
        "--wheels-share", type=float, default=0.1, help="share of rounds run in the wheels tier (default: %(default)s)"
    )
    b.add_argument("--seed", type=int, default=0, help="seed of the episodes (default: %(default)s)")
    b.add_argument("--out", default="benchmarks/results/soak.json", help="JSON output (default: %(default)s)")
    b.set_defaults(func=_cmd_bench)
    b = bsub.add_parser(
        "fidelity",
        help="how closely the MuJoCo robot follows the Robotarium's unicycle model",
        description="Steady-state tracking over the admissible command range, and trajectory "
        "errors of 10 s random command sequences vs the Robotarium's Euler integration.",
    )
    b.add_argument("--seeds", type=int, default=50, help="random command sequences per tier (default: %(default)s)")
    b.add_argument("--out", default="benchmarks/results/fidelity.json", help="JSON output (default: %(default)s)")
    b.set_defaults(func=_cmd_bench)
    add_viz_bench_parser(bsub)
    _add_safety_bench_parser(bsub)


def _add_safety_bench_parser(bsub) -> None:
    """``comat bench safety`` on the bench sub-parsers."""
    b = bsub.add_parser(
        "safety",
        help="the safety battery at reality levels: contacts and collisions on true poses",
        description="Every scenario of the safety battery (head-on pairs, swaps of 4 and 8, 16 and 32 robots "
        "driven at one point, robots driven into the walls, a ring of 20 driven through its centre, "
        "bang-bang at full speed among 16 robots, a robot pinned in a corner; faults: a robot that stops "
        "while commanded, Wi-Fi dropouts that brake a robot, a stopped robot whose pose freezes, "
        "repeated poses with no noise, team-wide stalls of the script; and two robots started inside the safety "
        "distance), through "
        "each loop (--loops: comat's filter; the exported main.py with the Robotarium's barrier or "
        "with comat's shipped filter), in each tier and at each reality level, judged on true poses: "
        "contacts, Robotarium collisions, boundary exits, the closest projected points, recoveries, "
        "fallbacks and the distance left to the goals, for the episodes that really started in the "
        "loop's safe set and for all. Exit 1 if a safe start saw a contact or a collision. The JSON is "
        "rewritten after every row.",
    )
    b.add_argument(
        "--reality",
        nargs="+",
        choices=REALITY_LEVELS,
        default=["nominal"],
        help="reality levels (default: %(default)s)",
    )
    b.add_argument(
        "--tiers",
        nargs="+",
        choices=["wheels", "unicycle"],
        default=["unicycle", "wheels"],
        help="tiers (default: %(default)s)",
    )
    b.add_argument("--episodes", type=int, default=50, help="episodes per scenario (default: %(default)s)")
    b.add_argument(
        "--scenarios", nargs="+", choices=SCENARIO_NAMES + CROSSING_NAMES, default=None, help="scenarios (default: all)"
    )
    b.add_argument(
        "--loops",
        nargs="+",
        choices=LOOPS,
        default=list(DEFAULT_LOOPS),
        help="loops, side by side (default: %(default)s)",
    )
    b.add_argument("--seed", type=int, default=0, help="seed of the episodes and the layer (default: %(default)s)")
    b.add_argument(
        "--mismatch",
        action="store_true",
        help="the mismatch battery instead: the filter built for one reality, run in another (nominal's in "
        "stress, in a 2x slower plant, with a wrong-way robot, with a 25 %%-speed robot; stress's in nominal); "
        "scenarios default to swap4 converge16 bangbang16 antipodal16 lanes12, loops to comat, the first tier",
    )
    b.add_argument("--out", default="benchmarks/results/safety_reality.json", help="JSON output (default: %(default)s)")
    b.set_defaults(func=_cmd_safety)
