"""What each robot type chooses, empty and loaded (issue 30): a kept HMT policy plays U_val
(deterministic, 40 environments drawn from U_val's coalitions, one episode each) and the share of
each action (stay, +x, -x, +y, -y) is counted per type, for empty and for loaded robots. The
drop-off is at x < -1 m: a loaded robot should mostly choose -x.

    python results/stability/actions.py results/stability/screen/runs/control_hmt_s2_150000 ...
"""

import sys

import numpy as np

import comat


def action_shares(folder: str, envs: int = 40, seed: int = 2_000_003) -> dict:
    """{(type id, loaded): (5,) shares of the actions}."""
    policy = comat.load_policy(folder, deterministic=True)
    vec = comat.make_vec_env("hmt_v0", envs, seed=seed, coalitions="val", tier="unicycle")
    obs, info = vec.reset()
    core, live = vec.core, np.ones(envs, dtype=bool)
    counts = {(t, loaded): np.zeros(5) for t in (0, 1) for loaded in (False, True)}
    for _ in range(core.task.horizon):
        mask = info["agent_mask"]
        actions = policy.act(obs, mask)
        load = core.state["load"] > 0
        for (t, loaded), c in counts.items():
            c += np.bincount(actions[mask & (core.type_ids == t) & live[:, None] & (load == loaded)], minlength=5)
        obs, _, term, trunc, info = vec.step(actions)
        live &= ~(term | trunc)
        if not live.any():
            break
    vec.close()
    return {k: c / max(c.sum(), 1) for k, c in counts.items()}


def main(folders: list[str]) -> None:
    print("Shares of stay / +x / -x / +y / -y (%), deterministic, U_val:\n")
    print("| policy | fast, empty | slow, empty | fast, loaded | slow, loaded |")
    print("|---|---|---|---|---|")
    for f in folders:
        s = action_shares(f)
        cells = [" / ".join(f"{100 * v:.0f}" for v in s[k]) for k in ((0, False), (1, False), (0, True), (1, True))]
        print(f"| {f.rstrip('/').split('/')[-1]} | " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
