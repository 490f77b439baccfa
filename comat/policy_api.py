"""A trained policy in plain Python: ``comat.load_policy(path_or_name)``.

    import comat

    env = comat.make_env("pcp_v0", coalitions="test", tier="unicycle")
    policy = comat.load_policy("pretrained:comat-pcp")
    observations, infos = env.reset(seed=0)
    while env.agents:
        observations, rewards, terminations, truncations, infos = env.step(policy(observations))

``path_or_name`` is a policy file (``policy.pt``), a checkpoint, a run folder, or one of the
policies that ship with comat (:data:`PRETRAINED`, ``"pretrained:comat-pcp"``). The returned
:class:`Policy` acts on one env's PettingZoo observation dict (``policy(obs) -> {agent: action}``)
and on batches (``policy.act(obs (B, N, D), mask (B, N)) -> (B, N)``); ``deterministic=False``
samples from the policy with its own random stream (``seed``), so the same seed gives the same
actions whatever else draws random numbers.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import torch

from comat.learners import learner_entry
from comat.rl import (
    PREFIX,
    PRETRAINED,
    act_with,
    load_trained,
    policy_file_of,
    policy_modules,
    pretrained_path,
    robot_slots,
)

__all__ = ["PRETRAINED", "Policy", "load_policy", "pretrained_path"]


class Policy:
    """A trained policy: ``policy(observations) -> actions`` on PettingZoo dicts, ``act`` on batches.

    Attributes: ``algo`` (the learner, :func:`comat.learners.learner_names`), ``task`` ("pcp",
    "hmt" ...), ``config`` (the run's :class:`comat.rl.config.RunConfig`), ``slots`` (robots it can
    act for: None = any team size, COMAT; else a team-sized learner's ``max_robots``), ``path`` (the
    file it was read from).
    """

    def __init__(self, modules: dict, config, path: Path, deterministic: bool = True, seed: int = 0) -> None:
        if not isinstance(deterministic, bool):
            raise TypeError(f"deterministic must be True or False, got {deterministic!r}")
        if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)):
            raise TypeError(f"seed must be an integer, got {seed!r} ({type(seed).__name__})")
        entry = learner_entry(config.algo)
        if not deterministic and not entry.samples:
            raise ValueError(
                f"deterministic=False: {entry.label} acts greedily (it explores epsilon-greedily only while it "
                "trains), so it has no policy to sample from; use deterministic=True"
            )
        self.modules, self.config, self.path = modules, config, Path(path)
        self.algo, self.task, self.slots = config.algo, config.task, robot_slots(config)
        self.deterministic = deterministic
        self._generator = torch.Generator().manual_seed(int(seed))
        self._obs_dim = modules[entry.acts_with[0]].layout.obs_dim

    def __repr__(self) -> str:
        slots = "any team size" if self.slots is None else f"{self.slots} robot slots"
        mode = "deterministic" if self.deterministic else "sampling"
        return f"Policy({self.algo} on {self.task}, {slots}, {mode}, from {str(self.path)!r})"

    def act(self, obs: np.ndarray, mask: np.ndarray | None = None) -> np.ndarray:
        """Actions (B, N) int64 for observations (B, N, D) (or one team's (N, D): actions (N,)) and
        the mask of real robots (B, N) (default: all). Padded slots get action 0."""
        obs = np.asarray(obs, dtype=np.float32)
        single = obs.ndim == 2
        if single:
            obs = obs[None]
        if obs.ndim != 3 or obs.shape[-1] != self._obs_dim:
            raise ValueError(
                f"obs must be (B, N, {self._obs_dim}) or (N, {self._obs_dim}) for a {self.task} "
                f"policy, got shape {obs.shape if not single else obs.shape[1:]}"
            )
        B, N, _ = obs.shape
        mask = np.ones((B, N), bool) if mask is None else np.asarray(mask, dtype=bool).reshape(B, N)
        if self.slots is not None:
            if N > self.slots:
                raise ValueError(
                    f"this {self.algo} policy acts for at most {self.slots} robots (its max_robots), "
                    f"got a team of {N}; COMAT policies take any size"
                )
            obs = np.concatenate([obs, np.zeros((B, self.slots - N, obs.shape[-1]), np.float32)], 1)
            mask = np.concatenate([mask, np.zeros((B, self.slots - N), bool)], 1)
        o, m = torch.as_tensor(obs), torch.as_tensor(mask)
        with torch.no_grad():
            generator = None if self.deterministic else self._generator
            a = act_with(self.algo, self.modules, o, m, self.deterministic, generator)
        actions = a.numpy()[:, :N].astype(np.int64)
        return actions[0] if single else actions

    def __call__(self, observations: dict[str, Any]) -> dict[str, int]:
        """One env's actions: ``{agent: action}`` for the agents in ``observations`` (a PettingZoo
        parallel env's dict, agents named ``robot_<i>``), robots ordered by their index."""
        if not isinstance(observations, dict) or not observations:
            raise ValueError(
                f"observations must be a non-empty dict {{agent: observation}} (a PettingZoo parallel "
                f"env's), got {type(observations).__name__} {observations!r:.80}"
            )
        agents = sorted(observations, key=_robot_index)
        obs = np.stack([np.asarray(observations[a], dtype=np.float32) for a in agents])
        return {agent: int(action) for agent, action in zip(agents, self.act(obs))}


def _robot_index(agent: str) -> int:
    head, _, index = str(agent).rpartition("_")
    if head != "robot" or not index.isdigit():
        raise ValueError(f"observations' keys must be agent names robot_<i>, got {agent!r}")
    return int(index)


def load_policy(
    path_or_name: str | Path, *, deterministic: bool = True, seed: int = 0, task: str | None = None
) -> Policy:
    """A trained policy from a policy file, checkpoint, run folder or ``pretrained:NAME``.

    Args:
        path_or_name: ``policy.pt``, ``checkpoint.pt``, a run folder, or ``"pretrained:comat-pcp"``
            (:data:`PRETRAINED`).
        deterministic: the most likely action (default) or a sample from the policy.
        seed: the sampling stream's seed (``deterministic=False``).
        task: if given, the policy's task must be this one.

    Raises:
        ValueError: an unknown name, a missing file, a file that is not a comat policy (naming it).
    """
    text, flag = str(path_or_name), "load_policy: path_or_name"
    path = pretrained_path(text, flag) if text.startswith(PREFIX) else Path(text)
    if not path.exists():
        raise ValueError(
            f"load_policy: path_or_name must be a policy file, checkpoint, run folder or one of "
            f"{[PREFIX + k for k in PRETRAINED]}, got {text!r} (no such file)"
        )
    path = policy_file_of(path, None, flag=flag)
    modules, config = policy_modules(load_trained(path, task=task), path)
    return Policy(modules, config, path, deterministic=deterministic, seed=seed)
