"""The registered learners (:mod:`comat.learners`) behind one small interface: build, iterate
(collect + update), act.

``Dims`` are the sizes a model is built from (stored in checkpoints, so a policy can be
rebuilt without an environment). Team-sized learners (MAT, MAPPO, QMIX) get environments with
``max_robots`` robot slots from their model config (``BASELINE_ROBOTS``, 8, by default, as in the
paper; 20 to play U_scale); the others (COMAT, IPPO, CASH) get as many as their teams need.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
import torch

from comat.config import SafetyConfig, SimConfig
from comat.envs import make_vec_env
from comat.envs.outside import OutsideVectorEnv, is_outside
from comat.learners import learner_entry
from comat.models import ObsLayout
from comat.rl.config import RunConfig
from comat.rl.ppo import PPOTrainer
from comat.rl.qmix import QmixTrainer

__all__ = [
    "BASELINE_ROBOTS",
    "Dims",
    "Learner",
    "act_with",
    "build_modules",
    "env_slots",
    "make_learner",
    "policy_act",
    "robot_slots",
]

BASELINE_ROBOTS = 8
"""Default robot slots of the team-sized learners (``max_robots`` of their model configs)."""


def robot_slots(config) -> int | None:
    """Robot slots of the environments a run's policy plays in: None (as many as the team has) for a
    learner no part of which is sized by the team (COMAT, IPPO, CASH), the model config's
    ``max_robots`` for a team-sized one (:attr:`comat.learners.LearnerEntry.team_sized`)."""
    return config.model.max_robots if learner_entry(config.algo).team_sized else None


def env_slots(config) -> dict[str, int | None]:
    """``max_robots`` and ``state_robots`` of a run's environments: the team-sized learners'
    centralized state (MAPPO's critic, QMIX's mixer) covers all their slots; the others', unused,
    the default 8."""
    slots = robot_slots(config)
    return {"max_robots": slots, "state_robots": slots or BASELINE_ROBOTS}


@dataclass(frozen=True)
class Dims:
    obs_dim: int
    n_types: int
    n_caps: int
    state_dim: int

    @classmethod
    def of(cls, env) -> Dims:
        layout = ObsLayout.for_task(env.task)
        return cls(layout.obs_dim, layout.n_types, layout.n_caps, env.state_size())

    @property
    def layout(self) -> ObsLayout:
        return ObsLayout(self.obs_dim, self.n_types, self.n_caps)

    def to_dict(self) -> dict:
        return asdict(self)


def build_modules(algo: str, dims: Dims, model_config, acting_only: bool = False) -> dict[str, torch.nn.Module]:
    """The networks of learner ``algo``, freshly initialized (seed torch first for reproducible
    weights); ``acting_only``: only those deterministic acting needs
    (:attr:`comat.learners.LearnerEntry.acts_with`)."""
    entry = learner_entry(algo)
    modules = entry.build(dims, model_config, acting_only)
    wanted = set(entry.acts_with) if acting_only else None
    if not isinstance(modules, dict) or (wanted is not None and set(modules) != wanted):
        got = sorted(modules) if isinstance(modules, dict) else type(modules).__name__
        raise ValueError(
            f"learner {algo!r}: its builder {entry.builder} must return "
            + (f"the modules {sorted(wanted)} with acting_only" if wanted else "a dict of modules")
            + f", got {got}"
        )
    return modules


def act_with(
    algo: str,
    modules: dict[str, torch.nn.Module],
    obs: torch.Tensor,
    mask: torch.Tensor,
    deterministic: bool = True,
    generator: torch.Generator | None = None,
) -> torch.Tensor:
    """Actions (B, N) of learner ``algo``'s ``modules`` for ``obs`` (B, N, D) and ``mask`` (B, N), with
    no state: the most likely (QMIX: the greedy) action, or one sampled with ``generator``. Padded
    slots: action 0 where the learner acts greedily."""
    entry = learner_entry(algo)
    module = modules[entry.acts_with[0]]
    if not entry.samples:
        return torch.where(mask, module(obs, mask).argmax(-1), 0)
    return module.act(obs, mask, None, deterministic=deterministic, generator=generator)[0]


def policy_act(algo: str, modules: dict[str, torch.nn.Module]):
    """Deterministic numpy policy ``act(obs, mask, state) -> actions (B, N)`` (evaluation).

    ``state`` is accepted and ignored: a deterministic action never needs MAPPO's critic, so a
    policy acts on sets whose centralized state differs from training's (PCP's prey slots grow
    with U_scale's teams) and on a policy file that keeps no critic."""

    @torch.no_grad()
    def act(obs: np.ndarray, mask: np.ndarray, state: np.ndarray | None) -> np.ndarray:
        return act_with(algo, modules, torch.as_tensor(obs, dtype=torch.float32), torch.as_tensor(mask)).numpy()

    return act


class Learner:
    """One learner's trainer with a uniform loop interface."""

    def __init__(self, algo: str, modules: dict, trainer) -> None:
        self.algo, self.modules, self.trainer = algo, modules, trainer
        self.family = learner_entry(algo).family

    def set_progress(self, done: float) -> None:
        """The share of the run done before the next update (the PPO learning-rate schedule)."""
        if self.family == "ppo":
            self.trainer.set_progress(done)

    def iterate(self) -> tuple[list[dict], dict[str, float], int]:
        """Collect and learn once: finished episodes' metrics, training statistics, env steps."""
        if self.family == "qmix":
            before = self.trainer.env_steps
            episodes = self.trainer.collect()
            return episodes, self.trainer.update(), self.trainer.env_steps - before
        rollout, stats = self.trainer.iterate()
        T, B = rollout.rewards.shape
        return rollout.episodes, stats, T * B

    def state_dict(self) -> dict:
        return self.trainer.state_dict()

    def load_state_dict(self, state: dict) -> None:
        self.trainer.load_state_dict(state)


def make_learner(config, env, dims: Dims) -> Learner:
    """Modules and trainer for a :class:`comat.rl.config.RunConfig` on ``env``."""
    entry = learner_entry(config.algo)
    modules = build_modules(config.algo, dims, config.model)
    device = None if config.device == "cpu" else config.device  # on the CPU the update trains in place
    if entry.family == "qmix":
        trainer = QmixTrainer(modules["agents"], modules["mixer"], env, config.trainer, seed=config.seed, device=device)
    else:
        trainer = PPOTrainer(
            modules["policy"], env, config.trainer, seed=config.seed, use_state=entry.uses_state, device=device
        )
    return Learner(config.algo, modules, trainer)


def make_run_env(config: RunConfig, num_envs: int, seed: int, coalitions=None):
    """The run's environments (on ``coalitions``, default the run's own: :attr:`RunConfig.coalitions`),
    training and evaluation alike, at the run's reality layer: each
    episode (every reset and autoreset) draws its layer from its own generator, so a run at
    ``nominal`` trains under a freshly sampled layer every episode (domain randomization). An outside
    task (:mod:`comat.envs.outside`) has its own team and world: an :class:`OutsideVectorEnv`."""
    if is_outside(config.task):
        return OutsideVectorEnv(config.task, num_envs, seed=seed, max_robots=robot_slots(config))
    sim = SimConfig(tier=config.tier, threads=config.physics_threads)
    safety = None if config.loop == "comat" else SafetyConfig(loop=config.loop)
    return make_vec_env(
        config.env_id,
        num_envs,
        workers=min(config.env_workers, num_envs),
        seed=seed,
        sim=sim,
        coalitions=config.coalitions if coalitions is None else coalitions,
        reality=config.reality,
        safety=safety,
        **env_slots(config),
    )
