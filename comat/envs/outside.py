"""An environment comat did not write, under comat's trainer: a PettingZoo parallel env of one agent
type, batched as :class:`comat.envs.VectorEnv` batches comat's tasks.

An outside task is named ``outside:MODULE``, where ``MODULE.parallel_env()`` builds the env with its
own default settings (``outside:mpe2.simple_spread_v3``: PettingZoo's MPE, now the ``mpe2`` package,
``pip install 'comat[outside]'``). ``comat train --algo mappo --task outside:mpe2.simple_spread_v3``
trains on it, checkpoints, resumes and writes a policy file as on a comat task. It is the outside check
of issue 65: comat's trainer on dynamics, observations and rewards it did not write.

==================  ==================================================================================
agents              the env's ``possible_agents``: one type, no capabilities, every episode the same team
                    of N agents (slots in that order)
actions             ``Discrete(5)`` for every agent (comat's learners choose among 5 actions; MPE's are
                    no-op, left, right, down, up); actions (B, N)
observation         (B, N, 5 + D): ``[0, 0, 0, 0 | 1 | the env's own observation (D)]``. The five leading
                    features are comat's :class:`~comat.models.features.ObsLayout` ([x, y, cos, sin |
                    type one-hot]): the pose slots are unused (zeros) and the one type's one-hot is 1. An
                    MLP sees zeros and one more bias; MAT's input LayerNorm sees five more features
state               (B, S): the env's ``state()`` (MPE: every agent's observation, concatenated); an env
                    without one: the agents' own observations concatenated
reward              (B,): the mean of the agents' rewards this step (a team reward; an episode's return
                    is then the mean of the agents' returns, what BenchMARL logs as ``episode_reward``)
mask                (B, N): the agents still in ``env.agents`` (MPE: all N, the whole episode)
terminated          all agents terminated at the step ``env.agents`` empties; otherwise the episode was
                    truncated (MPE: at ``max_cycles``, 25 steps), and PPO bootstraps from ``final_obs``
horizon             the env's ``max_cycles`` (a PPO rollout's default length)
episode metrics     ``return`` and ``steps``; ``progress``, ``finished`` and ``collisions`` are NaN: an
                    outside env has no task progress, and its return is the measure of a run
learners            those whose :class:`~comat.learners.LearnerEntry` says ``outside_envs`` (IPPO, MAPPO,
                    MAT, QMIX): they read the observation as one vector plus the type one-hot. COMAT and
                    CASH read poses and capabilities at fixed places and are refused in one line
==================  ==================================================================================

Seeds: environment b of B draws each episode's ``reset(seed=...)`` from its own generator, spawned from
the run seed (:class:`numpy.random.SeedSequence`), so the same seed gives the same episodes.

Version history: v1 (issue 65), the adapter.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from typing import Any

import numpy as np
from gymnasium import spaces

__all__ = ["OUTSIDE_PREFIX", "OutsideTask", "OutsideVectorEnv", "is_outside", "make_outside_env", "play_outside"]

OUTSIDE_PREFIX = "outside:"
"""How a task name says it is an outside env: ``outside:MODULE``."""
LAYOUT_PREFIX = np.array([0.0, 0.0, 0.0, 0.0, 1.0])
"""The five features put before the env's own observation: unused pose slots [x, y, cos, sin] and the
one type's one-hot (module docstring)."""
N_ACTIONS = 5
"""Actions comat's learners choose among."""
_SEED_HIGH = 2**31 - 1
"""Episode seeds are drawn from [0, this)."""


def is_outside(task: Any) -> bool:
    """Whether ``task`` names an outside env (``outside:MODULE``)."""
    return isinstance(task, str) and task.startswith(OUTSIDE_PREFIX)


def make_outside_env(task: str):
    """A new PettingZoo parallel env of outside task ``task`` (``outside:MODULE``); one-line ValueError
    for a name that is not one, a module that does not import or has no ``parallel_env``."""
    if not is_outside(task) or not task[len(OUTSIDE_PREFIX) :]:
        raise ValueError(f"task must be {OUTSIDE_PREFIX}MODULE (e.g. outside:mpe2.simple_spread_v3), got {task!r}")
    name = task[len(OUTSIDE_PREFIX) :]
    hint = f"an outside task is {OUTSIDE_PREFIX}MODULE with MODULE.parallel_env(), e.g. outside:mpe2.simple_spread_v3"
    try:
        module = importlib.import_module(name)
    except Exception as err:  # whatever the import raises, said in one line
        why = err.msg if isinstance(err, ModuleNotFoundError) else f"{type(err).__name__}: {err}"
        extra = " (pip install 'comat[outside]')" if name.startswith("mpe2") else ""
        why = " ".join(str(why).split())
        raise ValueError(f"task {task!r}: module {name!r} did not import ({why}){extra}; {hint}") from err
    build = getattr(module, "parallel_env", None)
    if build is None:
        raise ValueError(f"task {task!r}: module {name!r} has no parallel_env(); {hint}")
    return build()


class OutsideTask:
    """What comat's trainer asks of a task, for an outside env: its ``name``, ``horizon``,
    ``obs_size()``, one type and no capabilities (:class:`~comat.models.features.ObsLayout`)."""

    capabilities: tuple[str, ...] = ()

    def __init__(self, name: str, env) -> None:
        agents = list(env.possible_agents)
        self.name, self.agents = name, agents
        self.types = ("agent",)
        spaces = [env.action_space(a) for a in agents]
        bad = [(a, s) for a, s in zip(agents, spaces) if getattr(s, "n", None) != N_ACTIONS or s.shape != ()]
        if bad:
            raise ValueError(
                f"task {name!r}: comat's learners choose among {N_ACTIONS} discrete actions, but agent {bad[0][0]!r} "
                f"has action space {bad[0][1]}"
            )
        shapes = {env.observation_space(a).shape for a in agents}
        if len(shapes) != 1 or len(next(iter(shapes))) != 1:
            raise ValueError(
                f"task {name!r}: one agent type needs one flat observation shape for every agent, got {sorted(shapes)}"
            )
        self.env_obs_size = next(iter(shapes))[0]
        self.horizon = getattr(env.unwrapped, "max_cycles", None)
        if isinstance(self.horizon, bool) or not isinstance(self.horizon, int) or self.horizon < 1:
            raise ValueError(
                f"task {name!r}: the env's max_cycles (its episode length, comat's horizon) must be a positive "
                f"integer, got {self.horizon!r}"
            )

    def obs_size(self) -> int:
        """D of comat's observation: the layout prefix and the env's own."""
        return len(LAYOUT_PREFIX) + self.env_obs_size

    def observe(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        """(N, 5 + D) comat observations of one env's observation dict (absent agents: zeros)."""
        out = np.zeros((len(self.agents), self.obs_size()))
        for i, a in enumerate(self.agents):
            if a in obs:
                out[i, : len(LAYOUT_PREFIX)] = LAYOUT_PREFIX
                out[i, len(LAYOUT_PREFIX) :] = obs[a]
        return out


class OutsideVectorEnv:
    """``num_envs`` copies of an outside env as padded arrays, with :class:`comat.envs.VectorEnv`'s
    interface: ``reset``, ``step`` (same-step autoreset; ``final_obs``, ``final_state``, ``episode``
    and ``_episode`` in the info where an episode ended), ``state``, ``agent_mask`` and the generator
    states of a checkpoint.

    Args:
        task: ``outside:MODULE``.
        num_envs: B.
        seed: seeds the episodes (same seed, same episodes).
        max_robots: robot slots a team-sized learner has; the env's N agents must fit (None: N).
    """

    def __init__(self, task: str, num_envs: int, *, seed: int | None = None, max_robots: int | None = None) -> None:
        if isinstance(num_envs, bool) or not isinstance(num_envs, int) or num_envs < 1:
            raise ValueError(f"num_envs must be a positive integer, got {num_envs!r}")
        self.envs = [make_outside_env(task) for _ in range(num_envs)]
        self.task = OutsideTask(task, self.envs[0])
        self.num_envs, self.max_robots = num_envs, len(self.task.agents)
        self.single_observation_space = spaces.Box(-np.inf, np.inf, (self.task.obs_size(),), np.float64)
        self.single_action_space = spaces.Discrete(N_ACTIONS)
        if max_robots is not None and max_robots < self.max_robots:
            raise ValueError(
                f"task {task!r} has {self.max_robots} agents, more than the learner's max_robots={max_robots} slots"
            )
        self._seed(seed)
        self._obs = np.zeros((num_envs, self.max_robots, self.task.obs_size()))
        self._mask = np.zeros((num_envs, self.max_robots), dtype=bool)
        self._returns = np.zeros(num_envs)
        self._steps = np.zeros(num_envs, dtype=np.int64)
        self._started = False

    def _seed(self, seed: int | None) -> None:
        self._rngs = [np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(self.num_envs)]

    def rng_state(self) -> list[dict]:
        """The environments' generator states (for checkpoints)."""
        return [rng.bit_generator.state for rng in self._rngs]

    def set_rng_state(self, states: list[dict]) -> None:
        """Restore generator states from :meth:`rng_state`."""
        if len(states) != self.num_envs:
            raise ValueError(f"expected {self.num_envs} generator states (one per environment), got {len(states)}")
        for rng, state in zip(self._rngs, states):
            rng.bit_generator.state = state

    @property
    def agent_mask(self) -> np.ndarray:
        """(B, N) True where a slot's agent is in the episode."""
        return self._mask.copy()

    def _reset_one(self, b: int) -> None:
        obs, _ = self.envs[b].reset(seed=int(self._rngs[b].integers(_SEED_HIGH)))
        self._obs[b] = self.task.observe(obs)
        self._mask[b] = [a in self.envs[b].agents for a in self.task.agents]
        self._returns[b], self._steps[b] = 0.0, 0

    def reset(self, seed: int | None = None, teams: None = None) -> tuple[np.ndarray, dict[str, Any]]:
        """Start a new episode in every environment; returns obs (B, N, D) and info (``agent_mask``).
        ``teams`` must be None: an outside env has one team, its own."""
        if teams is not None:
            raise ValueError(f"teams must be None for an outside env (it has one team, its own), got {teams!r:.80}")
        if seed is not None:
            self._seed(seed)
        for b in range(self.num_envs):
            self._reset_one(b)
        self._started = True
        return self._obs.copy(), self._info()

    def step(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """One env step of all environments with actions (B, N) (slots of absent agents are ignored).

        Returns obs (B, N, D), rewards (B,), terminated (B,), truncated (B,) and info with
        ``agent_mask``, and for finished episodes ``episode`` (metric -> (B,)), ``final_obs`` (B, N, D),
        ``final_state`` (B, S) and the mask ``_episode`` (B,).
        """
        if not self._started:
            raise RuntimeError("call reset() before step()")
        actions = np.asarray(actions)
        B, N = self.num_envs, self.max_robots
        if actions.shape != (B, N):
            raise ValueError(f"actions must have shape ({B}, {N}) (envs, agent slots), got {actions.shape}")
        real = actions[self._mask]
        if not np.issubdtype(actions.dtype, np.integer) or real.size and (real.min() < 0 or real.max() >= N_ACTIONS):
            raise ValueError(f"actions must be integers in [0, {N_ACTIONS}), got {real[:5].tolist()}")
        rewards, terminated, truncated = np.zeros(B), np.zeros(B, dtype=bool), np.zeros(B, dtype=bool)
        final_obs, final_state = np.zeros_like(self._obs), np.zeros((B, self.state_size()))
        for b, env in enumerate(self.envs):
            acting = [(i, a) for i, a in enumerate(self.task.agents) if self._mask[b, i]]
            obs, rew, term, _, _ = env.step({a: int(actions[b, i]) for i, a in acting})
            rewards[b] = np.mean([rew[a] for _, a in acting])
            self._returns[b] += rewards[b]
            self._steps[b] += 1
            self._obs[b] = self.task.observe(obs)
            self._mask[b] = [a in env.agents for a in self.task.agents]
            if not env.agents:  # the episode ended: all terminated, else the time limit (or a mix) cut it
                terminated[b] = all(term[a] for _, a in acting)
                truncated[b] = not terminated[b]
                final_obs[b], final_state[b] = self._obs[b], self._state_of(b)
        info = self._info()
        done = terminated | truncated
        if done.any():
            nan = np.where(done, np.nan, 0.0)
            info["episode"] = {
                "return": np.where(done, self._returns, 0.0),
                "steps": np.where(done, self._steps, 0).astype(float),
                **{name: nan.copy() for name in ("progress", "finished", "collisions")},
            }
            info.update({"_episode": done, "final_obs": final_obs, "final_state": final_state})
            for b in np.flatnonzero(done):
                self._reset_one(b)
            info["agent_mask"] = self._mask.copy()
        return self._obs.copy(), rewards, terminated, truncated, info

    def _info(self) -> dict[str, Any]:
        return {"agent_mask": self._mask.copy()}

    def _state_of(self, b: int) -> np.ndarray:
        env = self.envs[b]
        try:
            return np.asarray(env.state(), dtype=float).ravel()
        except NotImplementedError:  # no state of its own: the agents' observations, concatenated
            return self._obs[b, :, len(LAYOUT_PREFIX) :].ravel()

    def state(self) -> np.ndarray:
        """(B, S) global states (module docstring)."""
        return np.stack([self._state_of(b) for b in range(self.num_envs)])

    def state_size(self) -> int:
        """S, the length of :meth:`state` rows."""
        return self._state_of(0).shape[0]

    def release_solvers(self) -> None:
        """Nothing to release (comat's tasks drop their OSQP problems here)."""

    def close(self) -> None:
        for env in self.envs:
            env.close()


def play_outside(
    env: OutsideVectorEnv, act: Callable[[np.ndarray, np.ndarray, Any], np.ndarray], episodes: int, seed: int
) -> list[dict[str, float]]:
    """``episodes`` episodes of ``act(obs (B, N, D), mask (B, N), state) -> actions (B, N)``,
    ``env.num_envs`` at a time (chunk k reset with seed ``seed + k``): each episode's metrics
    (``return``, ``steps``; NaN ``progress``, ``finished``, ``collisions``)."""
    if isinstance(episodes, bool) or not isinstance(episodes, int) or episodes < 1:
        raise ValueError(f"episodes must be a positive integer, got {episodes!r}")
    rows: list[dict[str, float]] = []
    for k, start in enumerate(range(0, episodes, env.num_envs)):
        wanted = min(env.num_envs, episodes - start)
        obs, info = env.reset(seed=seed + k)
        found: list[dict[str, float] | None] = [None] * env.num_envs
        while any(f is None for f in found[:wanted]):
            obs, _, terminated, truncated, info = env.step(
                np.where(info["agent_mask"], act(obs, info["agent_mask"], None), 0)
            )
            for b in np.flatnonzero(terminated | truncated):
                if found[b] is None:
                    found[b] = {name: float(v[b]) for name, v in info["episode"].items()}
        rows += found[:wanted]
    return rows
