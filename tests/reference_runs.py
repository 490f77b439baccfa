"""One episode per coalition of a set with a reference policy, for the new tasks' headroom tests."""

import numpy as np

from comat.envs import make_vec_env
from comat.envs.heuristics import blind_actions, heuristic_actions
from comat.tasks import env_id
from comat.team import generate_coalitions


def mean_progress(task: str, split: str, act, seed: int = 5) -> float:
    """Mean final progress of ``act(core) -> actions (B, N)`` over one episode of each of the 20
    coalitions of ``split`` (unicycle tier)."""
    env = make_vec_env(env_id(task), 20, coalitions=split, tier="unicycle", seed=seed)
    env.reset(teams=generate_coalitions(task, split))
    progress, seen = np.zeros(20), np.zeros(20, bool)
    while not seen.all():
        info = env.step(act(env.core))[-1]
        if "episode" in info:
            new = info["_episode"] & ~seen
            progress[new], seen = info["episode"]["progress"][new], seen | info["_episode"]
    return float(progress.mean())


def headroom(task: str, split: str) -> dict[str, float]:
    """:func:`mean_progress` of the scripted reference and of its capability-blind twin."""
    return {
        "heuristic": mean_progress(task, split, heuristic_actions),
        "blind": mean_progress(task, split, blind_actions),
    }
