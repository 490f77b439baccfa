"""Where COMAT's slow robots are held (issue 30): a robot is *held* when it chose to move and its
pose moved less than 10 % of its waypoint step in that env step (``comat/envs/diagnostics.py``).
This plays a kept policy on U_val (deterministic, one episode per environment, 40 environments
drawn from U_val's coalitions) and sorts the slow robots' held steps by where they happen:

* *wall*: within 0.12 m of the arena's edge, the waypoint pointing out of the arena;
* *crowd*: another robot within 0.25 m;
* *other*: neither (held by the filter at a distance, or turning on the spot);

and by whether the robot is loaded and where it is (drop-off x < -1 m, zone 1, zone 2, between).

    python results/stability/held.py results/stability/screen/runs/control_hmt_s2_150000 ...
"""

from __future__ import annotations

import sys

import numpy as np

import comat
from comat import constants as C
from comat.task_logic import ACTIONS

EDGE_M, NEAR_M = 0.12, 0.25


def held_table(folder: str, envs: int = 40, seed: int = 2_000_003) -> dict:
    policy = comat.load_policy(folder, deterministic=True)
    vec = comat.make_vec_env("hmt_v0", envs, seed=seed, coalitions="val", tier="unicycle")
    obs, info = vec.reset()
    core = vec.core
    live = np.ones(envs, dtype=bool)
    counts = {
        k: 0
        for k in (
            "slow_steps",
            "held",
            "wall",
            "crowd",
            "other",
            "loaded",
            "drop",
            "zone1",
            "zone2",
            "between",
            "fast_steps",
            "fast_held",
        )
    }
    for _ in range(core.task.horizon):
        mask = info["agent_mask"]
        actions = policy.act(obs, mask)
        before = core.poses().copy()
        load = core.state["load"].copy()
        step = core.task.step_lengths(core.caps)
        slow = mask & (core.type_ids == 1) & live[:, None]
        fast = mask & (core.type_ids == 0) & live[:, None]
        obs, _, term, trunc, info = vec.step(actions)
        after = core.poses()
        done = term | trunc
        moved = np.linalg.norm(after[..., :2] - before[..., :2], axis=-1)
        ok = ~done[:, None]  # an env that just ended was reset: its poses are the next episode's
        held = (actions != 0) & (moved < 0.1 * step) & ok
        goal = before[..., :2] + ACTIONS[actions] * step[..., None]
        x, y = before[..., 0], before[..., 1]
        near_edge = (
            (goal[..., 0] < C.ARENA_X_MIN_M + EDGE_M)
            | (goal[..., 0] > C.ARENA_X_MAX_M - EDGE_M)
            | (goal[..., 1] < C.ARENA_Y_MIN_M + EDGE_M)
            | (goal[..., 1] > C.ARENA_Y_MAX_M - EDGE_M)
        )
        d = np.linalg.norm(before[:, :, None, :2] - before[:, None, :, :2], axis=-1)
        d[~(mask[:, :, None] & mask[:, None, :])] = np.inf
        d[:, np.arange(d.shape[1]), np.arange(d.shape[1])] = np.inf
        crowd = d.min(-1) < NEAR_M
        s = slow & ok
        h = s & held
        counts["slow_steps"] += int(s.sum())
        counts["held"] += int(h.sum())
        counts["wall"] += int((h & near_edge).sum())
        counts["crowd"] += int((h & ~near_edge & crowd).sum())
        counts["other"] += int((h & ~near_edge & ~crowd).sum())
        counts["loaded"] += int((h & (load > 0)).sum())
        z1 = x**2 + y**2 <= 0.35**2
        counts["drop"] += int((h & (x <= -1.0)).sum())
        counts["zone1"] += int((h & z1).sum())
        counts["zone2"] += int((h & (x >= 1.0)).sum())
        counts["between"] += int((h & (x > -1.0) & (x < 1.0) & ~z1).sum())
        counts["fast_steps"] += int((fast & ok).sum())
        counts["fast_held"] += int((fast & ok & held).sum())
        live &= ~done
        if not live.any():
            break
    vec.close()
    return counts


def main(folders: list[str]) -> None:
    print(
        "| policy | slow robots' steps held % | of the held: wall % | crowd % | other % | loaded % | in drop-off % "
        "| zone 1 % | zone 2 % | between % | fast robots' steps held % |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for f in folders:
        c = held_table(f)
        h = max(c["held"], 1)
        shares = [100 * c[k] / h for k in ("wall", "crowd", "other", "loaded", "drop", "zone1", "zone2", "between")]
        print(
            f"| {f.rstrip('/').split('/')[-1]} | {100 * c['held'] / max(c['slow_steps'], 1):.1f} | "
            + " | ".join(f"{v:.0f}" for v in shares)
            + f" | {100 * c['fast_held'] / max(c['fast_steps'], 1):.1f} |",
            flush=True,
        )


if __name__ == "__main__":
    main(sys.argv[1:])
