"""Where sensors_v2's clusters are lost (issue 65's diagnosis): for kept policies, the reference ladder and
two rules a robot can follow from its own observation alone, what became of every cluster and robot at the
end of U_val episodes (deterministic, 40 environments × ``--rounds`` episodes, episode seed 2,000,003; the
designed-on seed, fine for a diagnosis, not for a verdict). A markdown table on stdout.

    .venv/bin/python results/learnability/sensors.py [RUN_OR_CHECKPOINT ...] > sensors_diag.md

Columns: progress %; the share of wide and of narrow robots that covered a cluster at some step; each lost cluster (open at the end) as *tried* (a robot ended within 0.1 m of its
centre), of which *by an unable robot* (the nearest such robot's radius − 0.06 m is short of the need), or
*abandoned* (no robot near); per robot at the end: *covering* a cluster alone, *parked* (moved < 0.01 m in the
last step, covering none), *moving*; the task's coordination metric per step (clusters open while an able
robot stands idle, lower is better); the share of robot-steps spent on ``stay``; steps taken.

Own-observation rules (what a robot could do alone, no team plan), both with the task's drive and both
stopping once they cover a cluster: ``able`` drives to the nearest open cluster it can cover (observation
10–11), ``nearest`` to the nearest open cluster whatever its need (7–8). They bound what uncoordinated robots
reach with the pointers the observation hands them.

Descriptive: one policy per row; episodes are not independent seeds.
"""

import sys

import numpy as np
from navigation import ladder_rows  # this folder's (run as a script, the folder is on the path)

import comat

TASK, SPLIT, SEED, ENVS = "sensors_v2", "val", 2_000_003, 40
NEAR_M = 0.1


def own_view_rule(column: int):
    """A policy that drives each robot not yet covering a cluster to the cluster at observation ``column``."""

    def act(core):
        obs = core.observe()
        target = obs[..., 0:2] + obs[..., column : column + 2]
        has = (np.abs(obs[..., column : column + 2]).sum(-1) > 0) & (obs[..., 12] < 1 - 1e-9)
        return core.task.drive(core.state, core.poses(), core.caps, core.mask, target, has)

    return act


def play(act, learned: bool, rounds: int) -> dict:
    """``rounds`` × ENVS U_val episodes; ``act(obs, mask)`` for a learned policy, else ``act(core)``.
    Steps the task core directly (no auto-reset), so each episode's end state can be read."""
    keys = (
        "progress",
        "wide",
        "narrow",
        "tried",
        "unable",
        "abandoned",
        "covering",
        "parked",
        "moving",
        "idle",
        "stay",
        "steps",
    )
    stats = {k: [] for k in keys}
    task = None
    for r in range(rounds):
        vec = comat.make_vec_env(TASK, ENVS, seed=SEED + r, coalitions=SPLIT, tier="unicycle")
        vec.reset()
        core = vec.core
        task, mask, caps = core.task, core.mask.copy(), core.caps.copy()
        live = np.ones(ENVS, dtype=bool)
        idle, steps, stays, robot_steps = np.zeros(ENVS), np.zeros(ENVS), 0, 0
        end, ever = {}, np.zeros(mask.shape, dtype=bool)
        for _ in range(task.horizon):
            actions = act(core.observe(), core.mask) if learned else act(core)
            actions = np.where(core.mask, actions, 0).astype(np.int64)
            stays += ((actions == 0) & mask & live[:, None]).sum()
            robot_steps += (mask & live[:, None]).sum()
            res = core.step(actions)
            idle += np.where(live, task.coordination(core.state, core.poses(), core.type_ids, caps, mask), 0)
            steps += live
            ever |= task._whole(task._inside(core.state, core.poses(), caps, mask)).any(-1) & mask & live[:, None]
            ended = (res.terminated | res.truncated) & live
            for b in np.flatnonzero(ended):
                s = core.state
                inside = task._whole(task._inside(s, core.poses(), caps, mask))[b]  # (N, C) robot covers cluster
                end[b] = (
                    s["best"][b] / max(s["clusters"][b], 1),
                    task._open(s)[b].copy(),
                    inside.any(-1),
                    s["still"][b].copy(),
                    core.poses()[b, :, :2].copy(),
                    s["centres"][b].copy(),
                    s["need"][b].copy(),
                )
            live &= ~ended
            if not live.any():
                break
        tried = unable = abandoned = lost = 0
        cover = park = move = robots = 0
        for b in range(ENVS):
            prog, open_, covering, still, xy, centres, need = end[b]
            m = mask[b]
            d = np.linalg.norm(xy[:, None] - centres[None], axis=-1)  # (N, C)
            d = np.where(m[:, None], d, np.inf)
            for c in np.flatnonzero(open_):
                lost += 1
                i = int(np.argmin(d[:, c]))
                if d[i, c] < NEAR_M:
                    tried += 1
                    unable += caps[b, i, 0] - task.settle_m < need[c]
                else:
                    abandoned += 1
            cover += (covering & m).sum()
            park += (~covering & still & m).sum()
            move += (~covering & ~still & m).sum()
            robots += m.sum()
            stats["progress"].append(prog)
        for k, t in (("wide", 0), ("narrow", 1)):
            stats[k].append(ever[mask & (core.type_ids == t)].mean())
        for k, v in (
            ("tried", tried / max(lost, 1)),
            ("unable", unable / max(lost, 1)),
            ("abandoned", abandoned / max(lost, 1)),
            ("covering", cover / robots),
            ("parked", park / robots),
            ("moving", move / robots),
            ("idle", (idle / steps).mean()),
            ("stay", stays / robot_steps),
            ("steps", steps.mean()),
        ):
            stats[k].append(v)
    return {k: float(np.mean(v)) for k, v in stats.items()}


PERCENT = {"wide": "wide robots that ever covered", "narrow": "narrow", "tried": "lost: tried"}
PERCENT |= {"unable": "of which unable", "abandoned": "lost: abandoned", "covering": "robots covering"}
PERCENT |= {"parked": "parked", "moving": "moving"}
COLUMNS = (
    ("progress", "progress", "{:.1f}", 100),
    *((key, head, "{:.0f} %", 100) for key, head in PERCENT.items()),
    ("idle", "idle-able per step", "{:.3f}", 1),
    ("stay", "stay", "{:.0f} %", 100),
    ("steps", "steps", "{:.1f}", 1),
)
"""The table's columns: statistic, header, format, scale."""


def main(folders: list[str], rounds: int = 2) -> None:
    rules = {"own view: able": own_view_rule(10), "own view: nearest": own_view_rule(7)}
    print("| policy | " + " | ".join(head for _, head, _, _ in COLUMNS) + " |")
    print("|---|" + "---:|" * len(COLUMNS))
    for name, s in ladder_rows(folders, play, SPLIT, rules, rounds):
        print(f"| {name} | " + " | ".join(fmt.format(scale * s[key]) for key, _, fmt, scale in COLUMNS) + " |")


if __name__ == "__main__":
    main(sys.argv[1:])
