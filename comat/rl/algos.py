"""The four algorithms behind one small interface: build, iterate (collect + update), act.

``Dims`` are the sizes a model is built from (stored in checkpoints, so a policy can be
rebuilt without an environment). Fixed-size baselines (MAT, MAPPO, QMIX) get environments with
``max_robots`` robot slots from their model config (``BASELINE_ROBOTS``, 8, by default, as in the
paper; 20 to play U_scale); COMAT gets as many as its teams need.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
import torch

from comat.config import SafetyConfig, SimConfig
from comat.envs import make_vec_env
from comat.models.cash import Cash
from comat.models.comat import Comat
from comat.models.features import ObsLayout
from comat.models.ippo import Ippo
from comat.models.mappo import Mappo
from comat.models.mat import Mat
from comat.models.qmix import QmixAgents, QmixMixer
from comat.rl.config import RunConfig
from comat.rl.ppo import PPOTrainer
from comat.rl.qmix import QmixTrainer

__all__ = [
    "ACTING_MODULES",
    "BASELINE_ROBOTS",
    "Dims",
    "Learner",
    "build_modules",
    "env_slots",
    "make_learner",
    "policy_act",
    "robot_slots",
]

BASELINE_ROBOTS = 8
"""Default robot slots of the fixed-size baselines (``max_robots`` of their model configs)."""


def robot_slots(config) -> int | None:
    """Robot slots of the environments a run's policy plays in: None (as many as the team has) for
    COMAT, IPPO and CASH (no part of them is sized by the team), the model config's ``max_robots`` for
    the fixed-size baselines."""
    return None if config.algo in ("comat", "ippo", "cash") else config.model.max_robots


def env_slots(config) -> dict[str, int | None]:
    """``max_robots`` and ``state_robots`` of a run's environments: the baselines' centralized state
    (MAPPO's critic, QMIX's mixer) covers all their slots; COMAT's, unused, the default 8."""
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


ACTING_MODULES = {
    "comat": ("policy",),
    "mat": ("policy",),
    "mappo": ("policy",),
    "qmix": ("agents",),
    "ippo": ("policy",),
    "cash": ("policy",),
}
"""The modules deterministic acting needs, per algo: COMAT's and MAT's whole policy (their value
heads share the encoder the actions are decoded from), MAPPO's policy without its critic, QMIX's
agent network without the mixer. A policy file keeps exactly these weights."""


def build_modules(algo: str, dims: Dims, model_config, acting_only: bool = False) -> dict[str, torch.nn.Module]:
    """The networks of ``algo``, freshly initialized (seed torch first for reproducible weights);
    ``acting_only``: only those deterministic acting needs (:data:`ACTING_MODULES`)."""
    if algo == "comat":
        return {"policy": Comat(dims.layout, model_config)}
    if algo == "mat":
        return {"policy": Mat(dims.layout, model_config)}
    if algo == "mappo":
        return {"policy": Mappo(dims.layout, dims.state_dim, model_config, critic=not acting_only)}
    if algo == "ippo":
        return {"policy": Ippo(dims.layout, model_config, critic=not acting_only)}
    if algo == "cash":
        return {"policy": Cash(dims.layout, model_config, critic=not acting_only)}
    if algo == "qmix":
        agents = {"agents": QmixAgents(dims.layout, model_config)}
        return agents if acting_only else {**agents, "mixer": QmixMixer(dims.state_dim, model_config)}
    raise ValueError(f"algo must be one of {list(ACTING_MODULES)}, got {algo!r}")


def uses_state(algo: str) -> bool:
    """Whether the trainer hands ``act`` ``env.state()`` (MAPPO's critic; QMIX's trainer reads it for
    its mixer by itself). Deterministic actions (:func:`policy_act`) never use it: MAPPO's actors
    read the robot's own observation, and MAPPO without a state (or without its critic) returns no
    values."""
    return algo == "mappo"


def policy_act(algo: str, modules: dict[str, torch.nn.Module]):
    """Deterministic numpy policy ``act(obs, mask, state) -> actions (B, N)`` (evaluation).

    ``state`` is accepted and ignored: a deterministic action never needs MAPPO's critic, so a
    policy acts on sets whose centralized state differs from training's (PCP's prey slots grow
    with U_scale's teams) and on a policy file that keeps no critic."""

    @torch.no_grad()
    def act(obs: np.ndarray, mask: np.ndarray, state: np.ndarray | None) -> np.ndarray:
        o = torch.as_tensor(obs, dtype=torch.float32)
        m = torch.as_tensor(mask)
        if algo == "qmix":
            return torch.where(m, modules["agents"](o, m).argmax(-1), 0).numpy()
        return modules["policy"].act(o, m, None, deterministic=True)[0].numpy()

    return act


class Learner:
    """One algorithm's trainer with a uniform loop interface."""

    def __init__(self, algo: str, modules: dict, trainer) -> None:
        self.algo, self.modules, self.trainer = algo, modules, trainer

    def set_progress(self, done: float) -> None:
        """The share of the run done before the next update (the PPO learning-rate schedule)."""
        if self.algo != "qmix":
            self.trainer.set_progress(done)

    def iterate(self) -> tuple[list[dict], dict[str, float], int]:
        """Collect and learn once: finished episodes' metrics, training statistics, env steps."""
        if self.algo == "qmix":
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
    modules = build_modules(config.algo, dims, config.model)
    device = None if config.device == "cpu" else config.device  # on the CPU the update trains in place
    if config.algo == "qmix":
        trainer = QmixTrainer(modules["agents"], modules["mixer"], env, config.trainer, seed=config.seed, device=device)
    else:
        trainer = PPOTrainer(
            modules["policy"], env, config.trainer, seed=config.seed, use_state=uses_state(config.algo), device=device
        )
    return Learner(config.algo, modules, trainer)


def make_run_env(config: RunConfig, num_envs: int, seed: int, coalitions=None):
    """The run's environments (on ``coalitions``, default the run's own: :attr:`RunConfig.coalitions`),
    training and evaluation alike, at the run's reality layer: each
    episode (every reset and autoreset) draws its layer from its own generator, so a run at
    ``nominal`` trains under a freshly sampled layer every episode (domain randomization)."""
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
