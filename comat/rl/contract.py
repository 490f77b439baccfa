"""What every registered learner must do, checked on a task's real observations: :func:`check_learner`.

The trainers, policy files, evaluation and the reports rely on these and nothing else of a learner
(:mod:`comat.learners`): its config fills from a preset block; ``build`` gives its family's modules
and, ``acting_only``, exactly those it acts with, whose weights are a part of the full learner's (a
policy file keeps them); acting ignores padded robot slots, gives each real robot an action in
0..4, and for a PPO learner ``evaluate_actions`` scores the actions ``act`` chose with the
log-probabilities ``act`` gave (an autoregressive one decoding with its cache as without it); a
team-sized learner's config says its slots, ``max_robots``.
"""

from __future__ import annotations

import dataclasses

import torch

from comat.learners import learner_entry
from comat.rl.algos import Dims, act_with, build_modules, make_run_env
from comat.rl.config import TRAINER_CONFIGS, RunConfig

__all__ = ["check_learner"]

N_ACTIONS = 5
"""The waypoint actions every task shares: stay, ±x, ±y."""
FAMILY_MODULES = {"ppo": {"policy"}, "qmix": {"agents", "mixer"}}
"""The modules each family's trainer trains (:data:`comat.learners.FAMILIES`)."""
LOGP_TOLERANCE = 1e-4
"""Largest difference allowed between ``act``'s and ``evaluate_actions``' log-probabilities (float32
rounding of two computations of one number)."""


def check_learner(name: str, task: str = "pcp", teams: int = 4, seed: int = 0) -> dict:
    """Check learner ``name`` on ``teams`` teams of ``task``'s training set with its config's defaults;
    ValueError (one line, naming the learner and what failed) at the first rule broken. Returns what
    was checked: ``modules``, ``acts_with``, ``parameters`` (all, acting), ``robot_slots``."""
    entry = learner_entry(name)
    where = f"learner {name!r}"
    cls = entry.config_class()
    if not (dataclasses.is_dataclass(cls) and cls.__dataclass_params__.frozen):
        raise ValueError(f"{where}: its config {entry.config} must be a frozen dataclass, got {cls!r}")
    try:
        model = cls()
    except TypeError as err:
        raise ValueError(f"{where}: its config {entry.config} must have a default for every field ({err})") from err
    slots = getattr(model, "max_robots", None)
    if entry.team_sized and not (isinstance(slots, int) and slots >= 1):
        raise ValueError(f"{where} is team-sized: its config must have max_robots (an int >= 1), got {slots!r}")
    trainer = TRAINER_CONFIGS[entry.family]()
    config = RunConfig(name, task, seed, "unicycle", 1, 1, 0, 1, trainer=trainer, model=model)
    torch.manual_seed(seed)
    env = make_run_env(config, teams, seed)
    try:
        obs, info = env.reset()
        dims = Dims.of(env)
        state = torch.as_tensor(env.state(), dtype=torch.float32)
    finally:
        env.close()
    full = build_modules(name, dims, model)
    acting = build_modules(name, dims, model, acting_only=True)
    if set(full) != FAMILY_MODULES[entry.family]:
        raise ValueError(
            f"{where}: its builder must return the {entry.family} modules {sorted(FAMILY_MODULES[entry.family])}, "
            f"got {sorted(full)}"
        )
    for key, module in acting.items():
        mine, theirs = module.state_dict(), full[key].state_dict()
        extra = [k for k in mine if k not in theirs or mine[k].shape != theirs[k].shape]
        if extra:
            raise ValueError(f"{where}: acting-only {key!r} weights {extra[:3]} are not the full learner's")
        full[key].eval()
    o, m = torch.as_tensor(obs, dtype=torch.float32), torch.as_tensor(info["agent_mask"])
    with torch.no_grad():
        _check_actions(where, act_with(name, full, o, m), m)
        padded = _padded(o, m, extra=not entry.team_sized)
        if not torch.equal(act_with(name, full, *padded)[:, : o.shape[1]], act_with(name, full, o, m)):
            raise ValueError(f"{where}: a padded robot slot changed the real robots' actions")
        if entry.family == "ppo":
            _check_ppo(where, entry, full["policy"], o, m, state if entry.uses_state else None, seed)
    return {
        "modules": sorted(full),
        "acts_with": list(entry.acts_with),
        "parameters": (_count(full), _count(acting)),
        "robot_slots": slots if entry.team_sized else None,
    }


def _count(modules: dict) -> int:
    return sum(p.numel() for module in modules.values() for p in module.parameters())


def _check_actions(where: str, actions: torch.Tensor, mask: torch.Tensor) -> None:
    if actions.shape != mask.shape or actions.dtype not in (torch.int64, torch.int32):
        raise ValueError(
            f"{where}: actions must be integers (B, N) = {tuple(mask.shape)}, "
            f"got {actions.dtype} {tuple(actions.shape)}"
        )
    real = actions[mask]
    if bool(((real < 0) | (real >= N_ACTIONS)).any()):
        raise ValueError(f"{where}: actions must be in 0..{N_ACTIONS - 1}, got {sorted(set(real.tolist()))}")


def _padded(obs: torch.Tensor, mask: torch.Tensor, extra: bool) -> tuple[torch.Tensor, torch.Tensor]:
    """The batch with noise, not zeros, in its padded robot slots (mask False), and with ``extra``
    one more such slot (a team-sized learner has no room for one)."""
    g = torch.Generator().manual_seed(1)
    obs = torch.where(mask[..., None], obs, torch.randn(obs.shape, generator=g))
    if not extra:
        return obs, mask
    noise = torch.randn((obs.shape[0], 1, obs.shape[2]), generator=g)
    return torch.cat([obs, noise], 1), torch.cat([mask, torch.zeros_like(mask[:, :1])], 1)


def _check_ppo(where: str, entry, policy, obs, mask, state, seed: int) -> None:
    g = torch.Generator().manual_seed(seed)
    actions, logp, values = policy.act(obs, mask, state, deterministic=False, generator=g)
    _check_actions(where, actions, mask)
    scored, entropy, scored_values = policy.evaluate_actions(obs, mask, actions, state)
    for what, x in (("act's log-probabilities", logp), ("evaluate_actions' entropy", entropy)):
        if x.shape != mask.shape:
            raise ValueError(f"{where}: {what} must be (B, N) = {tuple(mask.shape)}, got {tuple(x.shape)}")
    gap = float((scored - logp).abs().max())
    if gap > LOGP_TOLERANCE:
        raise ValueError(
            f"{where}: evaluate_actions scores the sampled actions {gap:.2g} away from act's log-probabilities "
            f"(at most {LOGP_TOLERANCE})"
        )
    if scored_values.shape != mask.shape or (values is not None and values.shape != mask.shape):
        raise ValueError(f"{where}: values must be (B, N) = {tuple(mask.shape)}, got {tuple(scored_values.shape)}")
    if entry.autoregressive:
        cached = policy.act(obs, mask, None, deterministic=True)[0]
        if not torch.equal(cached, policy.act_uncached(obs, mask, deterministic=True)[0]):
            raise ValueError(f"{where}: decoding with the cache chose other actions than act_uncached")
