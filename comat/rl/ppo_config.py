"""PPO's settings (:class:`PPOConfig`): what a preset's ``ppo`` section holds, checked on
construction. The trainer that reads them is :mod:`comat.rl.ppo` (which re-exports the class)."""

from __future__ import annotations

from dataclasses import dataclass

from comat.config import check_numbers

__all__ = ["CHOICES", "PPOConfig"]


@dataclass(frozen=True)
class PPOConfig:
    """PPO settings (defaults: MAT's, with the task's horizon as rollout length)."""

    num_envs: int = 32
    """Environments stepped together (the paper's batch size 32)."""
    rollout_steps: int | None = None
    """Vector steps per update (None: the task's horizon, one full episode per environment)."""
    epochs: int = 5
    """Passes over each rollout."""
    minibatches: int = 4
    """Minibatches per epoch (samples are whole teams at one step)."""
    lr: float = 5e-4
    lr_schedule: str = "constant"
    """``constant``: ``lr`` throughout. ``linear``: ``lr`` × (1 − the run's share of its env steps
    done), falling to 0 at ``total_env_steps`` (MAPPO's linear decay): a run extended with
    ``--resume --steps`` decays over its new length from then on."""
    clip: float = 0.2
    """PPO ratio clip ε."""
    entropy_coef: float = 0.01
    """σ, weight of the entropy bonus."""
    value_coef: float = 1.0
    max_grad_norm: float = 10.0
    gamma: float = 0.99
    gae_lambda: float = 0.95
    target_update_epochs: int = 2
    """The target critic V̄ is refreshed every this many epochs (paper: "every few epochs")."""
    huber_delta: float = 10.0
    value_target: str = "td"
    """``td``: eq. 6's one-step target r + γ·V̄(o') from the target critic. ``gae``: each
    robot's GAE(λ) return R_t = Â_t + V(o_t) from its own values at collection (MAT's code):
    rewards reach the episode start in one update instead of one step per target refresh."""
    advantage: str = "joint"
    """``joint`` (eq. 9): one GAE per team on V̂, the mean of its robots' values, given to each of its
    robots. ``per_robot``: each robot's GAE on its own value, δ_i = r + γ·V_i(o') − V_i(o) with the
    team's reward (BenchMARL's and TorchRL's multi-agent PPO; the IPPO of de Witt et al. 2020)."""
    normalize_advantage: bool = True
    """Standardize the advantages over the rollout (mean 0, std 1; ``per_robot``: over the real robots'
    entries). BenchMARL's MAPPO does not (its ``ClipPPOLoss(normalize_advantage=False)``)."""
    value_loss: str = "huber"
    """``huber`` (δ = ``huber_delta``) or ``mse``: the squared error, no ½ (TorchRL's ``l2``, the
    ``loss_critic_type`` of BenchMARL's MAPPO). Either is a mean over the real robots' entries."""
    value_norm: bool = True
    """Learn values normalized by a running ValueNorm of the targets (MAPPO's and MAT's code). False:
    the critic regresses to the raw targets (BenchMARL)."""
    grad_clip: str = "joint"
    """``joint``: one gradient-norm clip (``max_grad_norm``) over all parameters. ``separate``: the
    critic's parameters (those of a submodule named ``critic``) and the rest clipped each on its own,
    as BenchMARL's separate actor and critic optimizers are; Adam works per parameter, so one Adam
    over both then takes the same steps as two."""
    time_limit: str = "bootstrap"
    """What the horizon's cut means to the critic. ``bootstrap``: a truncated episode's last target
    is r + γ·V(final observation), as if the episode went on. ``terminal``: the horizon ends the
    episode, the last target is r alone. Where a task puts the steps left in its observation
    (navigation, warehouse) the time limit is part of the task: the final observation (0 steps
    left) is a state no training sample holds, its value an extrapolation, and Pardo et al. 2018
    ("Time limits in reinforcement learning") treat the cut as terminal; where the observation has
    no clock, bootstrapping is the consistent choice. QMIX's ``horizon_terminal`` is the same
    choice."""
    overlap: bool = False
    """Collect the next rollout while learning from this one: a thread acts with a copy of the
    policy from before the update while the update runs, so where the machine has cores to spare
    (more than the env workers and the learner's threads), collection and update overlap instead of
    taking turns. Each update then learns from a rollout of the policy one update older (a policy
    lag of one update), so its policy loss takes the decoupled form (:meth:`PPOTrainer.update`):
    the clip centred on the weights the update starts from, each term weighted by their
    probability over the collecting policy's. A different algorithm, compared with the default in
    ``results/overlap/``; off by default."""

    def __post_init__(self) -> None:
        check_numbers(
            self,
            "ppo",
            positive=("lr", "clip", "max_grad_norm", "huber_delta"),
            non_negative=("entropy_coef", "value_coef"),
            unit=("gae_lambda",),
            discount=("gamma",),
            at_least_one=("num_envs", "epochs", "minibatches", "target_update_epochs", "rollout_steps"),
        )
        for name in ("overlap", "normalize_advantage", "value_norm"):
            if not isinstance(getattr(self, name), bool):
                raise TypeError(f"ppo.{name} must be true or false, got {getattr(self, name)!r}")
        for name, choices in CHOICES.items():
            if getattr(self, name) not in choices:
                raise ValueError(f"ppo.{name} must be one of {list(choices)}, got {getattr(self, name)!r}")


VALUE_TARGETS = ("td", "gae")
LR_SCHEDULES = ("constant", "linear")
CHOICES = {
    "value_target": VALUE_TARGETS,
    "lr_schedule": LR_SCHEDULES,
    "advantage": ("joint", "per_robot"),
    "value_loss": ("huber", "mse"),
    "grad_clip": ("joint", "separate"),
    "time_limit": ("bootstrap", "terminal"),
}
"""PPOConfig's fields that name one of a few choices (the first of each is its default)."""
