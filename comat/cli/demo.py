"""``comat demo``: the robot world, every registered task and a shipped policy, in 2-4 minutes on 2 cores.

1. Physics and safety: teams of robots start on a ring and swap to the opposite side through
   the arena centre. Every command passes the barrier filter before the wheels; the same
   episodes run once more unfiltered, to show what it prevents.
2. Tasks: the scripted heuristic and a random policy play every registered task on training (U_train) and
   unseen (U_test) coalitions; the paper's metrics per row.
3. A trained policy: the COMAT policy that ships with comat (``pretrained:comat-pcp``) plays
   unseen (U_test) PCP teams: a Rerun recording, a video, and a Robotarium export checked under
   the installed ``rps``, written to ``--folder`` (default ``runs/demo``).
4. Learning (``--part train`` only, about 5-10 minutes): a quick COMAT (``--preset quick``) trains
   on PCP's training coalitions, then plays every training and unseen coalition next to a random
   policy.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from comat import constants as C
from comat.bench import run_scenario, swap_scenario
from comat.config import SimConfig
from comat.tasks import env_id, task_names

__all__ = ["run_demo"]


PARTS = ("all", "physics", "tasks", "pretrained", "train")
"""``--part`` choices; ``all`` runs every part but ``train``."""


def run_demo(
    tier: str = "wheels",
    robots: int = 8,
    episodes: int = 4,
    seed: int = 0,
    out: str | None = None,
    part: str = "all",
    folder: str = "runs/demo",
    command: Callable[[list[str]], int] | None = None,
) -> int:
    """Run the demo and print its summary; returns a process exit code (0 = all safe, and the
    pretrained policy's files written and checked). ``command(argv) -> exit code`` runs a ``comat``
    command line (:func:`comat.cli.main`, which passes itself: the pretrained part records, exports
    and checks the shipped policy exactly as a user would)."""
    if part not in PARTS:
        raise ValueError(f"--part must be one of {list(PARTS)}, got {part!r}")
    summary: dict = {"tier": tier, "seed": seed}
    ok = True
    if part in ("all", "physics"):
        phys_ok, summary["physics"] = _physics(tier, robots, episodes, seed)
        ok &= phys_ok
    if part in ("all", "tasks"):
        tasks_ok, summary["tasks"] = _tasks(tier, episodes, seed)
        ok &= tasks_ok
    if part in ("all", "pretrained"):
        if command is None:
            raise ValueError("run_demo: the pretrained part needs command= (comat.cli.main), got None")
        pre_ok, summary["pretrained"] = _pretrained(tier, episodes, seed, Path(folder), command)
        ok &= pre_ok
    if part == "train":
        summary["train"] = _train(seed)
    elif part == "all":
        print(
            "\ntrain your own: comat demo --part train (a quick COMAT on PCP, about 5-10 minutes), or "
            "comat train --algo comat --task pcp --preset quick"
        )
    if out:
        Path(out).parent.mkdir(parents=True, exist_ok=True)
        Path(out).write_text(json.dumps(summary, indent=2))
        print(f"wrote {out}")
    return 0 if ok else 1


def _physics(tier: str, robots: int, episodes: int, seed: int) -> tuple[bool, dict]:
    if robots < 2 or robots > 12:
        raise ValueError(f"--robots must be between 2 and 12 (they start on a 0.75 m ring), got {robots}")
    if episodes < 1:
        raise ValueError(f"--episodes must be >= 1, got {episodes}")
    ticks = 600  # 19.8 s: the barrier slows the crossing down; everyone gets through
    scn = swap_scenario(robots, episodes, seed, ticks=ticks)
    sim = SimConfig(tier=tier)
    print(
        f"comat demo: {episodes} team(s) of {robots} robots swap sides through the arena centre "
        f"({tier} tier, {sim.resolved_substeps} physics steps per {C.CONTROL_DT_S} s tick, "
        f"{ticks} ticks = {ticks * C.CONTROL_DT_S:.1f} s simulated)"
    )
    rows: dict = {}
    for label, filtered, reality in (
        ("safety filter", True, "off"),
        ("no filter", False, "off"),
        ("filter, nominal", True, "nominal"),
    ):
        t0 = time.perf_counter()
        r = run_scenario(scn, sim, filtered=filtered, reality=reality, seed=seed)
        rows[label] = {
            "min centre distance (m)": float(r.min_centre_distance.min()),
            "MuJoCo robot-robot contact ticks": int(r.robot_contacts.sum()),
            "Robotarium collisions (pair-ticks)": int(r.robotarium_collisions.sum()),
            "boundary exits (robot-ticks)": int(r.boundary_exits.sum()),
            "actuator errors (ticks)": int(r.actuator_errors.sum()),
            "filter interventions (team-ticks)": int(r.interventions.sum()) if filtered else 0,
            "filter fallbacks": int(r.fallbacks.sum()) if filtered else 0,
            "filter recoveries (outside the safe set)": int(r.recoveries.sum()) if filtered else 0,
            "robots within 5 cm of goal": f"{int((r.goal_error_robot < 0.05).sum())}/{robots * episodes}",
            "wall time (s)": round(time.perf_counter() - t0, 1),
        }
    width = max(len(k) for k in rows["safety filter"])
    print(f"{'':<{width}}  {'safety filter':>14}  {'no filter':>10}  {'filter, nominal':>15}")
    for key in rows["safety filter"]:
        a, b, c = rows["safety filter"][key], rows["no filter"][key], rows["filter, nominal"][key]
        fmt = (lambda v: f"{v:.3f}") if isinstance(a, float) and "distance" in key else str
        print(f"{key:<{width}}  {fmt(a):>14}  {fmt(b):>10}  {fmt(c):>15}")
    print(
        "filter, nominal: the same teams with the reality layer at nominal (late, noisy poses; lagging motors; "
        "start error): the filter decides on measured poses with its robust gain and margin, judged on true ones"
    )
    ok = True
    for safe in (rows["safety filter"], rows["filter, nominal"]):
        ok &= safe["MuJoCo robot-robot contact ticks"] == 0 and safe["Robotarium collisions (pair-ticks)"] == 0
        ok &= safe["boundary exits (robot-ticks)"] == 0
    print(
        "the filter kept every pair apart (bodies are 0.110 m wide; the barrier holds projected points "
        f"{C.SAFETY_DISTANCE_M} m apart)"
        if ok
        else "SAFETY VIOLATION with the filter on: please report this"
    )
    return ok, {"robots": robots, "episodes": episodes, "results": rows}


def _tasks(tier: str, episodes: int, seed: int) -> tuple[bool, dict]:
    from comat.envs import make_vec_env
    from comat.envs.heuristics import heuristic_actions, random_actions
    from comat.measure.episodes import run_episodes, summarize
    from comat.team import generate_coalitions

    rng = np.random.default_rng(seed)
    policies = {
        "heuristic": lambda env: lambda obs, mask, state: heuristic_actions(env.core),
        "random": lambda env: lambda obs, mask, state: random_actions(rng, mask),
    }
    print(
        f"\ntasks ({tier} tier): {episodes} coalitions per set, one episode each; heuristic = scripted with full task "
        "state; finished = share of episodes done before the horizon (PCP: all prey captured; HMT: all material "
        "delivered; the paper's completion), progress = the task's fraction done (docs/tasks.md)"
    )
    width = max(len(task) for task in ("task", *task_names())) + 1  # navigation, warehouse: wider than 'task'
    head = (
        f"{'task':<{width}}{'set':<7}{'policy':<11}{'finished':>11}{'progress':>9}{'steps':>7}{'return':>8}"
        f"{'collisions':>11}{'violations':>11}{'interv.':>9}{'time s':>8}"
    )
    print(head + "\n" + "-" * len(head))
    rows, ok = [], True
    for task in task_names():
        for split in ("train", "test"):
            teams = generate_coalitions(task, split)[:episodes]
            for name, policy in policies.items():
                env = make_vec_env(env_id(task), len(teams), seed=seed, tier=tier, coalitions=teams)
                t0 = time.perf_counter()
                res = run_episodes(env, policy(env), teams, seed)
                mean = summarize(res)  # the scalar metrics (rows also hold curves and per-robot lists)
                viol = mean["robotarium_collisions"] + mean["boundary_exits"]
                ok &= mean["collisions"] == 0 and viol == 0
                print(
                    f"{task:<{width}}{split:<7}{name:<11}{mean['finished']:>11.2f}{mean['progress']:>9.2f}"
                    f"{mean['steps']:>7.1f}"
                    f"{mean['return']:>8.2f}{mean['collisions']:>11.1f}{viol:>11.1f}{mean['interventions']:>9.0f}"
                    f"{time.perf_counter() - t0:>8.1f}"
                )
                rows.append({"task": task, "set": split, "policy": name, **mean})
    return ok, {"episodes": episodes, "rows": rows}


def _pretrained(
    tier: str, episodes: int, seed: int, folder: Path, comat: Callable[[list[str]], int]
) -> tuple[bool, dict]:
    """The shipped COMAT PCP policy on unseen teams: .rrd, video and a checked Robotarium export."""
    import shutil

    from comat.rl import PRETRAINED

    print(
        f"\npretrained policy: {PRETRAINED['comat-pcp']['what']}\n"
        f"{episodes} unseen U_test team(s), {tier} tier; files in {folder}/"
    )
    folder.mkdir(parents=True, exist_ok=True)
    rrd, video, export = folder / "comat_pcp.rrd", folder / "comat_pcp.mp4", folder / "robotarium_pcp"
    rc = comat(
        [
            "rollout",
            "--policy",
            "pretrained:comat-pcp",
            "--teams",
            "test",
            "--episodes",
            str(episodes),
            "--tier",
            tier,
            "--seed",
            str(seed),
            "--out",
            str(rrd),
            "--video",
            str(video),
            "--force",
        ]
    )
    shutil.rmtree(export, ignore_errors=True)  # the demo's own folder: a new export each time
    rc = rc or comat(
        ["export", "--policy", "pretrained:comat-pcp", "--team", "test:3", "--seed", str(seed), "--out", str(export)]
    )
    print(f"\nchecking {export} under the installed rps (the Robotarium's simulator) and in MuJoCo:")
    check = comat(["export", "--check", str(export), "--tier", tier]) if rc == 0 else 1
    ok = rc == 0 and check == 0
    print(
        f"\npretrained policy files: {rrd} (Rerun), {video} (video), {export}/ (upload to the Robotarium); "
        + ("all written and the export checked" if ok else "NOT all written or checked: see the errors above")
    )
    return ok, {"rrd": str(rrd), "video": str(video), "export": str(export), "ok": ok}


def _train(seed: int) -> dict:
    from comat.envs.base import resolve_coalitions
    from comat.envs.heuristics import random_actions
    from comat.measure.episodes import run_episodes, summarize
    from comat.rl import EVAL_SEED_OFFSET, load_policy, load_preset, make_run_env, resolve, train

    config = resolve(load_preset("quick"), "comat", "pcp", seed=seed)
    out = Path("runs") / f"demo-comat-pcp-{time.strftime('%Y%m%d-%H%M%S')}"
    print(
        f"\nlearning: COMAT on PCP ({config.tier} tier), {config.total_env_steps:,} env steps (--preset quick), "
        f"run folder {out}"
    )
    t0 = time.perf_counter()
    train(config, out)
    minutes = (time.perf_counter() - t0) / 60
    act, _ = load_policy(out / "checkpoint.pt")
    rng = np.random.default_rng(seed)
    rows = []
    head = f"{'policy':<16}{'set':<7}{'finished':>11}{'progress':>9}{'steps':>7}{'return':>8}{'collisions':>11}"
    print(f"trained in {minutes:.1f} min; one deterministic episode per coalition:\n{head}\n{'-' * len(head)}")
    for split in ("train", "test"):
        teams = resolve_coalitions(split, "pcp")
        env = make_run_env(config, len(teams), seed + EVAL_SEED_OFFSET, split)
        trained = summarize(run_episodes(env, act, teams, seed + EVAL_SEED_OFFSET))
        random = summarize(
            run_episodes(env, lambda obs, mask, state: random_actions(rng, mask), teams, seed + EVAL_SEED_OFFSET)
        )
        for name, r in (("COMAT (quick)", trained), ("random", random)):
            print(
                f"{name:<16}{split:<7}{r['finished']:>11.2f}{r['progress']:>9.2f}{r['steps']:>7.1f}"
                f"{r['return']:>8.2f}{r['collisions']:>11.1f}"
            )
            rows.append({"policy": name, "set": split, **r})
    print(f"continue training with: comat train --resume --out {out} --steps 1000000")
    return {"run": str(out), "minutes": minutes, "rows": rows}
