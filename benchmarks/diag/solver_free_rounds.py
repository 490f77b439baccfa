"""Usage: python benchmarks/diag/solver_free_rounds.py ROUNDS  (issue 21)

The soak's episodes over U_train, U_test and U_scale (12 vector envs of 32, seed 0), in rounds of
240 episodes. After each round every env's OSQP problems are dropped, then glibc's live malloc
bytes (mallinfo2: a leak raises them) and RSS after a trim are printed: with nothing held between
batches, a steady rise in either is drift, not the memory of the teams that ran last.
"""

import ctypes
import gc
import sys
import time

import numpy as np

from comat.bench import soak
from comat.envs import make_vec_env
from comat.envs.base import resolve_coalitions
from comat.envs.heuristics import random_actions
from comat.heap import release_free_heap


class MallInfo2(ctypes.Structure):
    _fields_ = [
        (n, ctypes.c_size_t)
        for n in (
            "arena",
            "ordblks",
            "smblks",
            "hblks",
            "hblkhd",
            "usmblks",
            "fsmblks",
            "uordblks",
            "fordblks",
            "keepcost",
        )
    ]


libc = ctypes.CDLL("libc.so.6")
libc.mallinfo2.restype = MallInfo2
seed, rng = 0, np.random.default_rng(0)
sets = ("train", "test", "scale")
combos = [(task, split, policy) for task in ("pcp", "hmt") for split in sets for policy in ("heuristic", "random")]
envs = {
    (task, split, tier): make_vec_env(f"{task}_v0", 32, seed=seed, tier=tier, coalitions=split)
    for task in ("pcp", "hmt")
    for split in sets
    for tier in ("unicycle", "wheels")
}
for env in envs.values():
    _, info = env.reset(seed=seed)
    for _ in range(3):
        _, _, _, _, info = env.step(random_actions(rng, info["agent_mask"]))
for r in range(int(sys.argv[1])):
    for task, split, policy in combos:
        tier = "wheels" if rng.random() < 0.1 else "unicycle"
        soak._episodes(envs[task, split, tier], policy, resolve_coalitions(split, task), seed + 1000 * r, rng)
    for env in envs.values():
        env.core.safe.forget_solver_state()
    gc.collect()
    release_free_heap()
    m = libc.mallinfo2()
    print(
        time.strftime("%H:%M:%S"),
        f"{(r + 1) * 240} episodes: RSS {soak._rss_bytes() / 2**20:.2f} MiB, "
        f"malloc in use {(m.uordblks + m.hblkhd) / 2**20:.2f} MiB",
        flush=True,
    )
