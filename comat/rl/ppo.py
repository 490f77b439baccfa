"""PPO for COMAT, MAT and MAPPO (paper eq. 6–9), readable top to bottom.

One update:

1. **Collect** ``rollout_steps`` vector steps from fresh episodes (every environment is reset at
   the start of a rollout, so an update depends only on the parameters and the random streams —
   which is what makes ``--resume`` continue exactly). Autoreset is same-step; where an episode
   ended, the next state of *that* episode is the env's ``final_obs``. With environments in
   several worker processes, the policy acts on one shard while the others simulate. With
   ``overlap`` the next rollout is collected in a thread while the update runs (one update of
   policy lag, corrected in step 4).
2. **Advantages** (eq. 9): joint GAE on V̂ = the mean of the robots' values, shared by the team's
   robots and normalized over the batch. ``advantage: per_robot``: each robot's GAE on its own
   value; ``normalize_advantage: false``: the raw advantages.
3. **Critic** (eq. 6): each robot's value regresses (Huber) to r_t + γ·V̄(o'_t) from a *target*
   critic V̄, refreshed (copied, targets recomputed) every ``target_update_epochs`` epochs;
   targets are normalized by a running ValueNorm. ``value_target: gae`` instead regresses each
   robot's value to its GAE(λ) return computed once per rollout, as MAT's code does;
   ``value_loss: mse`` squares the error; ``value_norm: false`` learns raw targets.
4. **Actor** (eq. 7–8): clipped importance ratio per robot times the joint advantage, plus an
   entropy bonus; one joint loss, one Adam step per minibatch, gradient-norm clipping (``grad_clip:
   separate``: the critic's gradient and the rest clipped each on its own). A lagged rollout
   (``overlap``) takes the decoupled form: ratios against the update's starting weights, terms
   weighted by their probability over the collecting policy's.

Padded robot slots are masked out of every loss and statistic (mask (T, B, N)). Each update's
statistics include the policy entropy of each robot type (``entropy_<type>``).

The options' defaults are the trainer as it was before them (issue 65 added them, every run since
unchanged bit for bit). BenchMARL's MAPPO (BenchMARL 1.5.2, TorchRL 0.11.1 ``ClipPPOLoss``) is
``advantage: per_robot, normalize_advantage: false, value_target: gae, value_loss: mse,
value_norm: false, grad_clip: separate`` (``results/benchmarl/matched/``).
"""

from __future__ import annotations

import copy
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, fields

import numpy as np
import torch
import torch.nn.functional as F

from comat.envs.sharded import ShardedVectorEnv
from comat.models import ObsLayout
from comat.rl.device import learner_copy, to_cpu
from comat.rl.gae import gae, standardize
from comat.rl.ppo_config import PPOConfig
from comat.rl.valuenorm import ValueNorm

__all__ = ["CollectionStopped", "PPOConfig", "PPOTrainer", "Rollout"]


@dataclass
class Rollout:
    """One rollout, (T, B, ...) tensors; ``next_*`` describe the state after each step in the
    same episode."""

    obs: torch.Tensor
    mask: torch.Tensor
    state: torch.Tensor | None
    actions: torch.Tensor
    logp: torch.Tensor
    values: torch.Tensor
    rewards: torch.Tensor
    terminated: torch.Tensor
    dones: torch.Tensor
    next_obs: torch.Tensor
    next_mask: torch.Tensor
    next_state: torch.Tensor | None
    episodes: list[dict]


class CollectionStopped(RuntimeError):
    """A collection ended early on request (``ppo.overlap``: the update beside it failed)."""


def _team_value(values: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """V̂: mean of the real robots' values, (..., N) -> (...)."""
    return (values * mask).sum(-1) / mask.sum(-1).clamp(min=1)


def _clip_groups(learner, grad_clip: str) -> list[list[torch.nn.Parameter]]:
    """The parameter lists clipped each on its own: all of them, or (``separate``) the critic's and
    the rest; a ValueError where the model has no submodule named ``critic``."""
    named = list(learner.named_parameters())
    if grad_clip == "joint":
        return [[p for _, p in named]]
    critic = [p for name, p in named if "critic" in name.split(".")]
    rest = [p for name, p in named if "critic" not in name.split(".")]
    if not critic or not rest:
        raise ValueError(
            f"ppo.grad_clip=separate needs a model with a submodule named 'critic' and parameters beside it, "
            f"got {type(learner).__name__} with parameters {[n for n, _ in named][:6]}..."
        )
    return [rest, critic]


class _Parts:
    """How :meth:`PPOTrainer.collect` steps the environments: as one part, the policy and the
    env taking turns; or, for a :class:`~comat.envs.ShardedVectorEnv` of several workers, one
    part per worker, the policy choosing one shard's next actions while the others simulate
    (their steps overlap; the sampling stream is drawn shard by shard)."""

    def __init__(self, env, with_state: bool) -> None:
        self.env, self.with_state = env, with_state
        self.overlapped = isinstance(env, ShardedVectorEnv) and env.workers > 1
        self.slices = env.slices if self.overlapped else [slice(0, env.num_envs)]
        self._actions: np.ndarray | None = None

    def send(self, p: int, actions: np.ndarray) -> None:
        if self.overlapped:
            self.env.step_send(p, actions, self.with_state)
        else:
            self._actions = actions

    def recv(self, p: int) -> tuple:
        """(obs, rewards, terminated, truncated, info, state or None) of part ``p``'s step."""
        if self.overlapped:
            result = self.env.step_recv(p)
            return result if self.with_state else (*result, None)
        result = self.env.step(self._actions)
        return (*result, self.env.state() if self.with_state else None)


class PPOTrainer:
    """Trains ``policy`` (COMAT, MAT or MAPPO interface) on a :class:`comat.envs.VectorEnv`.

    Args:
        policy: has ``act``, ``evaluate_actions`` and ``values``.
        env: the vector environment (its ``num_envs`` must equal ``config.num_envs``).
        config: PPO settings.
        seed: seeds the action sampling and the minibatch order.
        use_state: pass ``env.state()`` to the policy (MAPPO's centralized critic).
        device: None to learn in place on the CPU; else the update runs on a copy of the policy
            on this device, mirrored to the CPU policy after every update (:mod:`comat.rl.device`).
    """

    def __init__(
        self, policy, env, config: PPOConfig, seed: int, use_state: bool = False, device: str | None = None
    ) -> None:
        if env.num_envs != config.num_envs:
            raise ValueError(f"env has {env.num_envs} environments, config.num_envs is {config.num_envs}")
        self.policy, self.env, self.config = policy, env, config
        self.use_state = use_state
        self.device = device
        self.learner = learner_copy(policy, device)  # acting stays on `policy`, on the CPU
        # fused: one kernel for all parameters instead of a loop of small ones (~5 % of an update)
        self.optimizer = torch.optim.Adam(self.learner.parameters(), lr=config.lr, eps=1e-5, fused=True)
        self.clip_groups = _clip_groups(self.learner, config.grad_clip)
        self.layout = ObsLayout.for_task(env.task)  # where each robot's type is (its entropy is logged per type)
        self.type_names = tuple(env.task.types)
        self.target = copy.deepcopy(self.learner).requires_grad_(False)
        self.value_norm = ValueNorm().to(device or "cpu")
        self.generator = torch.Generator().manual_seed(seed)
        self.rng = np.random.default_rng(seed)
        # ``overlap``: the copy that acts while the update changes ``policy``, and the rollout it
        # collected, which the next update learns from.
        self.acting = copy.deepcopy(policy).requires_grad_(False) if config.overlap else policy
        self.pending: Rollout | None = None
        self.timing: dict[str, float] = {}
        """Seconds of the last :meth:`iterate`: ``collect_s`` and ``update_s``; with ``overlap``,
        ``update_s`` and ``wait_s`` (waiting after the update for the collection beside it)."""

    def set_progress(self, done: float) -> None:
        """The share (0–1) of the run's env steps done before the next update: sets the learning
        rate of ``lr_schedule`` (a no-op for ``constant``)."""
        if self.config.lr_schedule == "linear":
            for group in self.optimizer.param_groups:
                group["lr"] = self.config.lr * max(0.0, 1.0 - done)

    # -- helpers --------------------------------------------------------------------------------
    def _state(self) -> torch.Tensor | None:
        return torch.as_tensor(self.env.state(), dtype=torch.float32) if self.use_state else None

    def _denorm_values(self, values: torch.Tensor) -> torch.Tensor:
        return self.value_norm.denormalize(values) if self.config.value_norm else values

    def _value_targets(self, raw: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        """What the critic regresses to: ``raw`` normalized by the ValueNorm, updated on the real
        robots' entries first (``value_norm``), or ``raw`` itself."""
        if not self.config.value_norm:
            return raw
        self.value_norm.update(raw[mask])
        return self.value_norm.normalize(raw)

    # -- 1. collect -----------------------------------------------------------------------------
    def _act_send(self, policy, parts: _Parts, p: int, obs, mask, state):
        actions, logp, values = policy.act(obs, mask, state, generator=self.generator)
        parts.send(p, actions.numpy())
        return actions, logp, values

    @torch.no_grad()
    def collect(self, policy=None, stop: threading.Event | None = None) -> Rollout:
        """One rollout from fresh episodes, acted by ``policy`` (default: the trainer's); ``stop``,
        once set, ends it at the next step with :class:`CollectionStopped`."""
        policy = self.policy if policy is None else policy
        env, T = self.env, self.config.rollout_steps or self.env.task.horizon
        parts = _Parts(env, self.use_state)
        obs_np, info = env.reset()
        state_all = self._state()
        # Per part: current obs (b, N, D), mask (b, N), state (b, S) or None.
        cur = [
            (
                torch.as_tensor(obs_np[sl], dtype=torch.float32),
                torch.as_tensor(info["agent_mask"][sl]),
                None if state_all is None else state_all[sl],
            )
            for sl in parts.slices
        ]
        keys = tuple(f.name for f in fields(Rollout) if f.name != "episodes")
        steps: list[dict[str, list]] = [{k: [] for k in keys} for _ in parts.slices]
        episodes: list[dict] = []
        threads = torch.get_num_threads()
        if parts.overlapped:
            torch.set_num_threads(1)  # the env workers have the other cores
        try:
            acted = [self._act_send(policy, parts, p, *cur[p]) for p in range(len(parts.slices))]
            for t in range(T):
                if stop is not None and stop.is_set():
                    raise CollectionStopped(f"collection stopped at step {t} of {T}")
                for p in range(len(parts.slices)):
                    obs, mask, state = cur[p]
                    actions, logp, values = acted[p]
                    next_np, rewards, terminated, truncated, info, next_state_np = parts.recv(p)
                    next_obs = torch.as_tensor(next_np, dtype=torch.float32)
                    next_mask = torch.as_tensor(info["agent_mask"])
                    next_state = None if next_state_np is None else torch.as_tensor(next_state_np, dtype=torch.float32)
                    done = terminated | truncated
                    # The next state of the same episode: the final observation where it just ended.
                    ep_obs, ep_mask = next_obs.clone(), next_mask.clone()
                    ep_state = None if next_state is None else next_state.clone()
                    if done.any():
                        d = torch.as_tensor(done)
                        ep_obs[d] = torch.as_tensor(info["final_obs"], dtype=torch.float32)[d]
                        ep_mask[d] = mask[d]
                        if ep_state is not None:
                            ep_state[d] = torch.as_tensor(info["final_state"], dtype=torch.float32)[d]
                        for b in np.flatnonzero(done):
                            episodes.append({k: float(v[b]) for k, v in info["episode"].items()})
                    for key, value in (
                        ("obs", obs),
                        ("mask", mask),
                        ("state", state),
                        ("actions", actions),
                        ("logp", logp),
                        ("values", values),
                        ("rewards", torch.as_tensor(rewards, dtype=torch.float32)),
                        ("terminated", torch.as_tensor(terminated)),
                        ("dones", torch.as_tensor(done)),
                        ("next_obs", ep_obs),
                        ("next_mask", ep_mask),
                        ("next_state", ep_state),
                    ):
                        steps[p][key].append(value)
                    cur[p] = (next_obs, next_mask, next_state)
                    if t + 1 < T:
                        acted[p] = self._act_send(policy, parts, p, *cur[p])
        finally:
            torch.set_num_threads(threads)
        stacked = {
            k: (torch.cat([torch.stack(s[k]) for s in steps], dim=1) if steps[0][k][0] is not None else None)
            for k in keys
        }
        return Rollout(**stacked, episodes=episodes)

    def iterate(self) -> tuple[Rollout, dict[str, float]]:
        """Collect and update once: the rollout learned from and the update's statistics.

        With ``overlap`` the rollout learned from is the one collected beside the previous update
        (the first is collected first, by the same policy), and the next is collected by a thread,
        acting with the weights from before this update, while this update runs.
        """
        t0 = time.perf_counter()
        if not self.config.overlap:
            ro = self.collect()
            t1 = time.perf_counter()
            stats = self.update(ro)
            self.timing = {"collect_s": t1 - t0, "update_s": time.perf_counter() - t1}
            return ro, stats
        lagged = self.pending is not None  # else the first rollout, collected by these very weights
        ro = self.pending if lagged else self.collect()
        self.pending = None
        self.acting.load_state_dict(self.policy.state_dict())  # the weights before this update
        threads = torch.get_num_threads()
        stop = threading.Event()
        with ThreadPoolExecutor(1, thread_name_prefix="collect") as pool:
            t1 = time.perf_counter()
            future = pool.submit(self._collect_aside, stop)
            try:
                stats = self.update(ro, lagged=lagged)
            except BaseException:
                stop.set()  # an update that fails (or Ctrl-C) does not wait for a whole rollout
                raise
            t2 = time.perf_counter()
            self.pending = future.result()
        torch.set_num_threads(threads)  # torch's default for new threads, which the collector set to 1
        self.timing = {"collect_s": t1 - t0, "update_s": t2 - t1, "wait_s": time.perf_counter() - t2}
        return ro, stats

    def _collect_aside(self, stop: threading.Event) -> Rollout:
        # One torch thread (a thread's own setting in OpenMP): the update has the others.
        torch.set_num_threads(1)
        return self.collect(self.acting, stop)

    # -- 2-4. update ----------------------------------------------------------------------------
    def _next_values(self, net, ro: Rollout) -> torch.Tensor:
        """Per-robot values (T, B, N) of the next states under ``net`` (0 after termination, and
        after the horizon's cut with ``time_limit: terminal``)."""
        T, B, N, D = ro.next_obs.shape
        state = None if ro.next_state is None else ro.next_state.reshape(T * B, -1)
        v = net.values(ro.next_obs.reshape(T * B, N, D), ro.next_mask.reshape(T * B, N), state).reshape(T, B, N)
        ended = ro.dones if self.config.time_limit == "terminal" else ro.terminated
        return self._denorm_values(v) * (~ended)[..., None]

    @torch.no_grad()
    def advantages(self, ro: Rollout) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        """Step 2 for a rollout: V̂ (T, B), the robots' next values (T, B, N), the GAE returns
        V̂ + Â (T, B) and the advantages as the update uses them (T, B), on the learner's device.
        With ``advantage: per_robot`` the update gives each robot its own; here the returns and the
        advantages are then their means over the team's robots (what ``comat probe`` reports)."""
        ro = self._on_device(ro)
        v_hat, next_values, returns, adv, _ = self._advantages(ro)
        if adv.dim() == 3:
            adv = _team_value(adv, ro.mask.to(torch.float32))
        return v_hat, next_values, returns, adv

    @torch.no_grad()
    def _robot_gae(self, ro: Rollout, next_values: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Each robot's GAE on its own values (T, B, N) and its GAE(λ) return, with the team's reward
        (padded slots: meaningless, masked out by every use)."""
        v = self._denorm_values(ro.values)
        rewards, dones = ro.rewards[..., None].expand_as(v), ro.dones[..., None].expand_as(v)
        return gae(rewards, v, next_values, dones, self.config.gamma, self.config.gae_lambda)

    @torch.no_grad()
    def _advantages(self, ro: Rollout) -> tuple[torch.Tensor, ...]:
        """:meth:`advantages` on a rollout on the learner's device, with the advantages as the update
        uses them ((T, B) for ``joint``, (T, B, N) for ``per_robot``) and, for ``per_robot``, each
        robot's GAE(λ) return (T, B, N) (else None)."""
        cfg = self.config
        mask = ro.mask.to(torch.float32)
        next_values = self._next_values(self.learner, ro)
        if cfg.advantage == "joint":
            v_hat = _team_value(self._denorm_values(ro.values), mask)
            v_next_hat = _team_value(next_values, ro.next_mask.to(torch.float32))
            adv, returns = gae(ro.rewards, v_hat, v_next_hat, ro.dones, cfg.gamma, cfg.gae_lambda)
            robot_returns = None
        else:
            adv, robot_returns = self._robot_gae(ro, next_values)
            adv = adv * mask
            v_hat, returns = _team_value(self._denorm_values(ro.values), mask), _team_value(robot_returns, mask)
        if cfg.normalize_advantage:
            adv = standardize(adv, ro.mask)
        return v_hat, next_values, returns, adv, robot_returns

    def _on_device(self, ro: Rollout) -> Rollout:
        if self.device is None:
            return ro
        return Rollout(
            **{
                f.name: (v.to(self.device) if isinstance(v := getattr(ro, f.name), torch.Tensor) else v)
                for f in fields(Rollout)
            }
        )

    def update(self, ro: Rollout, lagged: bool = False) -> dict[str, float]:
        # long: PPO's epoch loop reads like cleanrl's: losses, clipping and stats in one place, as the paper writes them
        """Steps 2-4 on ``ro``; ``lagged``: ``ro`` was collected by the weights one update older than
        the learner's (``overlap``), which the policy loss then corrects for (below)."""
        cfg = self.config
        ro = self._on_device(ro)
        T, B, N, D = ro.obs.shape
        _, next_values, _, adv, robot_returns = self._advantages(ro)
        flat = {
            "obs": ro.obs.reshape(T * B, N, D),
            "mask": ro.mask.reshape(T * B, N),
            "state": None if ro.state is None else ro.state.reshape(T * B, -1),
            "actions": ro.actions.reshape(T * B, N),
            "logp": ro.logp.reshape(T * B, N),
            "adv": adv.reshape(T * B, -1),  # (T·B, 1): the team's; (T·B, N): each robot's
        }
        # Each robot's type, for the entropy per type: (T·B, N, K) one-hot, padded slots zero.
        types = F.one_hot(self.layout.types(flat["obs"]), len(self.type_names)) * flat["mask"][..., None]
        type_entropy = torch.zeros(len(self.type_names), device=types.device)
        stats: dict[str, list[float]] = {
            "policy_loss": [],
            "value_loss": [],
            "entropy": [],
            "approx_kl": [],
            "clip_frac": [],
        }
        lag_weight = None
        if cfg.overlap:
            # A lagged rollout's ratios against its own (behaviour) policy start away from 1, and a
            # clip centred there let COMAT's policy run away (results/overlap/: clip fraction 0.76
            # by 69 k env steps). So the clip is centred on the weights this update starts from (the
            # proximal policy) and each robot's term is weighted by π_prox / π_behaviour, which
            # corrects for the lag: the decoupled objective of Hilton et al. 2021 ("Batch
            # size-invariance for policy optimization"). Unlagged, π_prox is the behaviour policy.
            lag_kl = 0.0
            if lagged:
                with torch.no_grad():
                    prox = self.learner.evaluate_actions(flat["obs"], flat["mask"], flat["actions"], flat["state"])[0]
                    log_w = (prox - flat["logp"]) * flat["mask"]
                    lag_weight = torch.exp(log_w)
                    n_real = flat["mask"].sum().clamp(min=1)
                    lag_kl = float(((lag_weight - 1) - log_w).sum() / n_real)  # KL(behaviour ‖ proximal), estimated
                flat["logp"] = prox
            stats["lag_kl"] = [lag_kl]
        targets = None
        if cfg.value_target == "gae":
            with torch.no_grad():
                # Per robot: the team reward, the robot's own values; padded slots are masked out.
                raw = robot_returns if robot_returns is not None else self._robot_gae(ro, next_values)[1]
                targets = self._value_targets(raw, ro.mask).reshape(T * B, N)
        for epoch in range(cfg.epochs):
            if cfg.value_target == "td" and epoch % cfg.target_update_epochs == 0:
                # Refresh V̄ and its TD targets r + γ·V̄(o'); update the normalizer on them.
                self.target.load_state_dict(self.learner.state_dict())
                with torch.no_grad():
                    # In epoch 0 the target is the policy that gave next_values: no second pass.
                    if epoch:
                        next_values = self._next_values(self.target, ro)
                    raw = ro.rewards[..., None] + cfg.gamma * next_values
                    targets = self._value_targets(raw, ro.mask).reshape(T * B, N)
            order = self.rng.permutation(T * B)
            for idx in np.array_split(order, cfg.minibatches):
                idx_t = torch.as_tensor(idx, device=self.device)
                m = flat["mask"][idx_t]
                mf = m.to(torch.float32)
                n_real = mf.sum().clamp(min=1)
                state = None if flat["state"] is None else flat["state"][idx_t]
                logp, entropy, values = self.learner.evaluate_actions(
                    flat["obs"][idx_t], m, flat["actions"][idx_t], state
                )
                ratio = torch.exp(logp - flat["logp"][idx_t])
                a = flat["adv"][idx_t]
                surrogate = torch.min(ratio * a, ratio.clamp(1 - cfg.clip, 1 + cfg.clip) * a)
                if lag_weight is not None:
                    surrogate = surrogate * lag_weight[idx_t]
                policy_loss = -(surrogate * mf).sum() / n_real
                entropy_mean = (entropy * mf).sum() / n_real
                if cfg.value_loss == "huber":
                    errors = F.huber_loss(values, targets[idx_t], reduction="none", delta=cfg.huber_delta)
                else:
                    errors = F.mse_loss(values, targets[idx_t], reduction="none")
                value_loss = (errors * mf).sum() / n_real
                loss = policy_loss - cfg.entropy_coef * entropy_mean + cfg.value_coef * value_loss
                self.optimizer.zero_grad(set_to_none=True)
                loss.backward()
                for group in self.clip_groups:
                    torch.nn.utils.clip_grad_norm_(group, cfg.max_grad_norm)
                self.optimizer.step()
                with torch.no_grad():
                    log_ratio = (logp - flat["logp"][idx_t]) * mf
                    stats["approx_kl"].append(float(((ratio - 1) * mf - log_ratio).sum() / n_real))
                    stats["clip_frac"].append(float((((ratio - 1).abs() > cfg.clip) * mf).sum() / n_real))
                    type_entropy += (entropy[..., None] * types[idx_t]).sum((0, 1))
                stats["policy_loss"].append(policy_loss.item())
                stats["value_loss"].append(value_loss.item())
                stats["entropy"].append(entropy_mean.item())
        if self.learner is not self.policy:
            self.policy.load_state_dict(self.learner.state_dict())  # the next rollout acts with these
        # Per type: the mean over every robot-step of the type that the update's minibatches scored
        # (NaN for a type no team of the rollout has).
        counts = types.sum((0, 1)) * cfg.epochs
        per_type = (type_entropy / counts).tolist()
        return {
            **{k: float(np.mean(v)) for k, v in stats.items()},
            **{f"entropy_{name}": h for name, h in zip(self.type_names, per_type)},
        }

    # -- checkpoint state -------------------------------------------------------------------------
    def state_dict(self) -> dict:
        return {
            "policy": self.policy.state_dict(),
            "target": to_cpu(self.target.state_dict()),
            "optimizer": to_cpu(self.optimizer.state_dict()),
            "value_norm": to_cpu(self.value_norm.state_dict()),
            "generator": self.generator.get_state(),
            "rng": self.rng.bit_generator.state,
            # overlap: the rollout collected beside the last update, which the next one learns from
            "pending": None if self.pending is None else _rollout_state(self.pending),
        }

    def load_state_dict(self, state: dict) -> None:
        self.policy.load_state_dict(state["policy"])
        if self.learner is not self.policy:
            self.learner.load_state_dict(state["policy"])
        self.target.load_state_dict(state["target"])
        self.optimizer.load_state_dict(state["optimizer"])
        self.value_norm.load_state_dict(state["value_norm"])
        self.generator.set_state(state["generator"])
        self.rng.bit_generator.state = state["rng"]
        pending = state.get("pending")  # absent in checkpoints from before ``overlap``
        if pending is not None and not self.config.overlap:
            raise ValueError(
                "the checkpoint holds a rollout collected for ppo.overlap=true (the next update's), "
                "but this run has ppo.overlap=false; resume it with ppo.overlap=true"
            )
        self.pending = None if pending is None else Rollout(**pending)


def _rollout_state(ro: Rollout) -> dict:
    """A rollout as a checkpoint's plain data (tensors on the CPU, episodes as dicts)."""
    return {f.name: to_cpu(getattr(ro, f.name)) for f in fields(Rollout)}
