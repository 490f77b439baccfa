"""Where navigation_v1's goals are lost (issue 65's diagnosis): for a policy and the reference ladder, and
for two rules a robot can follow from its own observation alone, what became of every goal and robot at
the end of U_val episodes (deterministic, 40 environments × ``--rounds`` episodes, episode seed 2,000,003;
the designed-on seed, fine for a diagnosis, not for a verdict). A markdown table on stdout.

    .venv/bin/python results/learnability/navigation.py [RUN_OR_CHECKPOINT ...] > navigation.md
    .venv/bin/python results/learnability/navigation.py --noise     # the planners with ε random actions
    .venv/bin/python results/learnability/navigation.py --slack     # a v2 design probe: other reach shares

Columns: progress %; each lost goal (open at the end) as *chased* (a free robot ended within 0.3 m of it:
it went for it and did not claim it in time or did not stop on it) or *abandoned* (no free robot near it);
per free robot at the end (it claimed nothing): *doubled* (it ended within 0.3 m of a goal a teammate
claimed: two robots went for one goal), *wandering* (neither near an open nor a claimed goal); the
per-step share of goals stranded (the task's coordination metric, lower is better); the share of a
robot's first 3 steps it chose ``stay`` (hesitation costs: goals lie at 0.9–1.0 of a robot's reach).

Own-observation rules (what a robot could do alone, no team plan): ``nearest`` drives to the nearest open
goal of its view (observation 10–12), ``farthest`` to the farthest one it can still reach (16–18); both
stop there (the task's own drive). They bound what uncoordinated robots reach.

Descriptive: one policy per row; episodes are not independent seeds.
"""

import sys

import numpy as np

import comat
from comat.envs.heuristics import reference_policy

TASK, SPLIT, SEED, ENVS = "navigation_v1", "val", 2_000_003, 40
NEAR_M = 0.3


def own_view_rule(column: int):
    """A policy that drives each free robot to the goal at observation ``column`` (offset x, y)."""

    def act(core):
        obs, mask = core.observe(), core.mask
        target = obs[..., 0:2] + obs[..., column : column + 2]
        has = (np.abs(obs[..., column : column + 3]).sum(-1) > 0) & (obs[..., 7] < 0.5)
        return core.task.drive(core.state, core.poses(), core.caps, mask, target, has)

    return act


def play(act, learned: bool, rounds: int) -> dict:
    """Run ``rounds`` × ENVS U_val episodes; ``act(obs, mask)`` for a learned policy, else ``act(core)``.
    Steps the task core directly (no auto-reset), so each episode's end state can be read."""
    stats = {k: [] for k in ("progress", "chased", "abandoned", "doubled", "wandering", "stranded", "hesitate")}
    for r in range(rounds):
        vec = comat.make_vec_env(TASK, ENVS, seed=SEED + r, coalitions=SPLIT, tier="unicycle")
        vec.reset()
        core = vec.core
        mask = core.mask.copy()
        live = np.ones(ENVS, dtype=bool)
        stranded, steps, stays, first = np.zeros(ENVS), np.zeros(ENVS), np.zeros(ENVS), np.zeros(ENVS)
        end = {}
        for t in range(core.task.horizon):
            actions = act(core.observe(), core.mask) if learned else act(core)
            actions = np.where(core.mask, actions, 0).astype(np.int64)
            if t < 3:
                stays += ((actions == 0) & mask).sum(1)
                first += mask.sum(1)
            stranded += np.where(
                live, core.task.coordination(core.state, core.poses(), core.type_ids, core.caps, mask), 0
            )
            steps += live
            res = core.step(actions)
            ended = (res.terminated | res.truncated) & live
            for b in np.flatnonzero(ended):
                end[b] = (
                    core.state["claimed"][b].copy(),
                    core.state["done_robot"][b].copy(),
                    core.poses()[b, :, :2].copy(),
                )
            live &= ~ended
            if not live.any():
                break
        goals, active = core.state["goals"], core.state["active"]
        claimed = np.stack([end[b][0] for b in range(ENVS)])
        done = np.stack([end[b][1] for b in range(ENVS)])
        centres = np.stack([end[b][2] for b in range(ENVS)])
        stats["progress"].append(((claimed & active).sum(1) / active.sum(1)).mean())
        d = np.linalg.norm(centres[:, :, None] - goals[:, None], axis=-1)  # (B, N, K)
        free = mask & ~done
        open_ = active & ~claimed
        near = d < NEAR_M
        lost = open_.sum()
        chased = (open_ & (near & free[..., None]).any(1)).sum()
        stats["chased"].append(chased / max(lost, 1))
        stats["abandoned"].append((lost - chased) / max(lost, 1))
        doubled = free & (near & (claimed & active)[:, None]).any(2)
        wandering = free & ~(near & active[:, None]).any(2)
        n_free = max(free.sum(), 1)
        stats["doubled"].append(doubled.sum() / n_free)
        stats["wandering"].append(wandering.sum() / n_free)
        stats["stranded"].append((stranded / steps).mean())
        stats["hesitate"].append((stays / first).mean())
    return {k: float(np.mean(v)) for k, v in stats.items()}


def noise_table(rounds: int = 2, levels=(0.0, 0.05, 0.1, 0.2)) -> None:
    """How much each planner loses when a share of its actions is replaced by uniformly random ones
    (each robot, each step, with probability ε; one generator, seed 0): how brittle the task is to
    the imperfect execution a learned policy has."""
    print("| planner | " + " | ".join(f"ε = {e:g}" for e in levels) + " |")
    print("|---|" + "---:|" * len(levels))
    for name in ("heuristic", "blind"):
        cells = []
        for eps in levels:
            rng = np.random.default_rng(0)

            def act(core, n=name, e=eps, rng=rng):
                a = reference_policy(n, core, 0, SPLIT)(None, core.mask, None)
                return np.where(rng.random(a.shape) < e, rng.integers(0, 5, a.shape), a)

            cells.append(f"{100 * play(act, False, rounds)['progress']:.1f}")
        print(f"| {name} | " + " | ".join(cells) + " |")


def slack_table(rounds: int = 2, fractions=((0.9, 1.0), (0.75, 0.9), (0.6, 0.75))) -> None:
    """A design probe for a navigation_v2 (not a version): the ladder with goals at other shares of
    their robot's reach (``Navigation.reach_fraction``, v1: 0.9–1.0), on U_val without and with 10 %
    random actions and on U_cap. The question: does a planner that knows the speeds, executing with
    10 % errors, still beat the blind planner executing perfectly?"""
    from comat.tasks.navigation import Navigation

    global SPLIT
    kept = Navigation.reach_fraction, SPLIT
    cols = [("val", "heuristic", 0.0), ("val", "heuristic", 0.1), ("val", "type_only", 0.0), ("val", "blind", 0.0)]
    cols += [("val", "blind", 0.1), ("capability", "heuristic", 0.0), ("capability", "type_only", 0.0)]
    cols += [("capability", "blind", 0.0)]
    print("| reach share | " + " | ".join(f"{s} {n}{' ε 0.1' if e else ''}" for s, n, e in cols) + " |")
    print("|---|" + "---:|" * len(cols))
    try:
        for frac in fractions:
            Navigation.reach_fraction = frac
            cells = []
            for split, name, eps in cols:
                SPLIT = split
                rng = np.random.default_rng(0)

                def act(core, n=name, e=eps, rng=rng, sp=split):
                    a = reference_policy(n, core, 0, sp)(None, core.mask, None)
                    return np.where(rng.random(a.shape) < e, rng.integers(0, 5, a.shape), a)

                cells.append(f"{100 * play(act, False, rounds)['progress']:.1f}")
            print(f"| {frac[0]:g}–{frac[1]:g} | " + " | ".join(cells) + " |")
    finally:
        Navigation.reach_fraction, SPLIT = kept


def ladder_rows(folders: list[str], play, split: str, rules: dict, rounds: int) -> list[tuple[str, dict]]:
    """(name, ``play``'s statistics) for each kept policy (deterministic), the planners of the
    reference ladder on ``split`` and each own-observation rule of ``rules`` (name -> ``act(core)``);
    also sensors.py's."""
    rows = []
    for folder in folders:
        policy = comat.load_policy(folder, deterministic=True)
        rows.append((folder.rstrip("/").split("/")[-1], play(policy.act, True, rounds)))
    for name in ("heuristic", "type_only", "blind"):
        rows.append(
            (name, play(lambda core, n=name: reference_policy(n, core, 0, split)(None, core.mask, None), False, rounds))
        )
    return rows + [(name, play(rule, False, rounds)) for name, rule in rules.items()]


def main(folders: list[str], rounds: int = 2) -> None:
    rules = {"own view: nearest": own_view_rule(10), "own view: farthest": own_view_rule(16)}
    rows = ladder_rows(folders, play, SPLIT, rules, rounds)
    print(
        "| policy | progress | lost goals chased | lost goals abandoned | free robots doubled | free robots wandering | stranded per step | stay in first 3 steps |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    for name, s in rows:
        print(
            f"| {name} | {100 * s['progress']:.1f} | {100 * s['chased']:.0f} % | {100 * s['abandoned']:.0f} % | "
            f"{100 * s['doubled']:.0f} % | {100 * s['wandering']:.0f} % | {s['stranded']:.3f} | {100 * s['hesitate']:.0f} % |"
        )


if __name__ == "__main__":
    if sys.argv[1:] == ["--noise"]:
        noise_table()
    elif sys.argv[1:] == ["--slack"]:
        slack_table()
    else:
        main(sys.argv[1:])
