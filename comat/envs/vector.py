"""B environments of one task as padded arrays: the trainer's view of the tasks.

All B teams run in one :class:`comat.envs.core.TaskCore` — one physics call per team size and
one safety QP per control tick for all of them. Teams differ in size; arrays are padded to
N = the largest team the environment may get, with ``agent_mask`` (B, N) marking real robots.

Autoreset is *same-step*: when an environment's episode ends, the step that ends it already
returns the first observation of its next episode (new team, new start); the finished
episode's last observation is in ``info["final_obs"]`` (its global state in
``info["final_state"]`` when every team fits the state's ``state_robots`` slots), its metrics in
``info["episode"]`` (:data:`comat.envs.core.EPISODE_METRICS`, and ``coordination`` for a task with a
coordination metric) and its record (:meth:`comat.envs.core.TaskCore.episode_detail`: progress
curve ``episode_curve``, per-robot counts ``episode_robots``, end counts ``episode_end``), all
valid where ``info["_episode"]`` is True.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces

from comat.envs.base import build_core
from comat.envs.core import EPISODE_METRICS
from comat.envs.options import EnvOptions
from comat.heap import release_free_heap
from comat.team import TeamSpec

__all__ = ["VectorEnv"]


class VectorEnv:
    """``num_envs`` environments of a task with per-episode team compositions.

    Args:
        task: a :mod:`comat.task_logic` task instance.
        num_envs: B.
        seed: seeds every environment's generator (same seed, same episodes).
        shard: ``(first, total)``: these are environments ``first … first + num_envs - 1`` of
            ``total`` seeded from ``seed`` (how :class:`comat.envs.sharded.ShardedVectorEnv`
            splits one seed over worker processes); None: all of them.
        **options: the env options (:class:`comat.envs.options.EnvOptions`: coalitions, team,
            tier, sim, safety, ticks_per_step, max_robots, state_robots, reality), as for
            :class:`comat.envs.base.TaskEnv`, except that the state covers 8 robots unless
            ``state_robots`` says otherwise.
    """

    def __init__(
        self, task, num_envs: int, *, seed: int | None = None, shard: tuple[int, int] | None = None, **options: Any
    ) -> None:
        if isinstance(num_envs, bool) or not isinstance(num_envs, int) or num_envs < 1:
            raise ValueError(f"num_envs must be a positive integer, got {num_envs!r}")
        self.task = task
        self.num_envs = num_envs
        first, total = shard if shard is not None else (0, num_envs)
        if not (0 <= first and first + num_envs <= total):
            raise ValueError(
                f"shard must be (first, total) with 0 <= first and first + num_envs <= total, got {shard!r}"
            )
        self._shard = (first, total)
        self.env_options = EnvOptions.of(options, "VectorEnv")
        """The env options these environments were made with."""
        self.coalitions, self.fixed_team, self.core = build_core(task, num_envs, self.env_options, state_robots=8)
        self.max_robots = self.core.N
        self.single_observation_space = spaces.Box(-np.inf, np.inf, (task.obs_size(),), np.float64)
        self.single_action_space = spaces.Discrete(5)
        self._seed(seed)
        self._started = False

    def _seed(self, seed: int | None) -> None:
        first, total = self._shard
        children = np.random.SeedSequence(seed).spawn(total)[first : first + self.num_envs]
        self._rngs = [np.random.default_rng(s) for s in children]

    def _draw(self, b: int) -> TeamSpec:
        if self.fixed_team is not None:
            return self.fixed_team
        return self.coalitions[int(self._rngs[b].integers(len(self.coalitions)))]

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
        """(B, N) True where a slot holds a robot of the current team."""
        return self.core.mask.copy()

    def reset(self, seed: int | None = None, teams: list[TeamSpec] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        """Start a new episode in every environment; returns obs (B, N, D) and info.

        ``teams`` (one per environment) sets this episode's teams instead of drawing them
        (evaluation: every coalition once); later episodes are drawn as usual.
        """
        if seed is not None:
            self._seed(seed)
        envs = np.arange(self.num_envs)
        if teams is None:
            teams = [self._draw(b) for b in envs]
        elif len(teams) != self.num_envs or not all(isinstance(t, TeamSpec) for t in teams):
            raise ValueError(
                f"teams must be a list of {self.num_envs} TeamSpec (one per environment), got {teams!r:.200}"
            )
        self.core.reset(envs, list(teams), [self._rngs[b] for b in envs])
        self._started = True
        release_free_heap()  # the last batch's transient peaks, held by glibc (comat.heap)
        return self.core.observe(), self._info()

    def step(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """One env step of all environments with actions (B, N) (padded slots are ignored).

        Returns obs (B, N, D), rewards (B,), terminated (B,), truncated (B,) and info with
        ``agent_mask``, ``reward/<term>`` (B,), and for finished episodes ``episode``
        (metric -> (B,)), ``final_obs`` (B, N, D), ``final_state`` (B, S), ``episode_curve`` (B, H),
        ``episode_robots`` (name -> (B, N)), ``episode_end`` (name -> (B,)) and the mask ``_episode`` (B,).
        """
        if not self._started:
            raise RuntimeError("call reset() before step()")
        actions = np.asarray(actions)
        B, N = self.num_envs, self.max_robots
        if actions.shape != (B, N):
            raise ValueError(f"actions must have shape ({B}, {N}) (envs, robot slots), got {actions.shape}")
        real = actions[self.core.mask]
        if not np.issubdtype(actions.dtype, np.integer) or real.size and (real.min() < 0 or real.max() > 4):
            bad = real[(real < 0) | (real > 4)] if np.issubdtype(actions.dtype, np.integer) else real
            raise ValueError(f"actions must be integers in [0, 5) (stay, +x, -x, +y, -y), got {bad[:5].tolist()}")
        res = self.core.step(actions.astype(np.int64))
        done = res.terminated | res.truncated
        info = {f"reward/{k}": v for k, v in res.terms.items()}
        if done.any():
            final_obs = self.core.observe()
            # The state covers state_robots slots; larger teams (COMAT only) have none.
            fits = not self.core.mask[:, self.core.state_robots :].any()
            final_state = self.core.global_state() if fits else None
            # Every task's metrics, then the task's own (its coordination metric, where it has one).
            metrics = {name: np.zeros(B) for name in EPISODE_METRICS}
            envs = np.flatnonzero(done)
            for b in envs:
                for name, value in self.core.episode_metrics(b).items():
                    metrics.setdefault(name, np.zeros(B))[b] = value
            info.update(self.core.episode_detail())
            self.core.reset(envs, [self._draw(b) for b in envs], [self._rngs[b] for b in envs])
            info.update({"episode": metrics, "_episode": done.copy(), "final_obs": final_obs})
            if final_state is not None:
                info["final_state"] = final_state
        info.update(self._info())
        return self.core.observe(), res.rewards, res.terminated, res.truncated, info

    def _info(self) -> dict[str, Any]:
        return {"agent_mask": self.core.mask.copy(), "type_ids": self.core.type_ids.copy()}

    def graph(self) -> dict[str, np.ndarray]:
        """Dense graphs of all teams, (B, N, ...) (see :meth:`TaskCore.graph`)."""
        return self.core.graph()

    def state(self) -> np.ndarray:
        """(B, S) centralized states (see :meth:`TaskEnv.state`)."""
        return self.core.global_state()

    def state_size(self) -> int:
        """S, the length of :meth:`state` rows."""
        return self.core.state_size()

    def teams(self) -> list[TeamSpec]:
        """The current team of every environment."""
        return list(self.core.teams)

    def release_solvers(self) -> None:
        """Drop the filter's OSQP problems and hand the freed heap back to the OS.

        For an environment that waits between batches of episodes (evaluation, the soak): it would
        otherwise hold its last batch's problems, set up for the teams that ran last, until its
        next full reset drops them anyway. Nothing a later episode computes changes (each batch
        starts with a full reset, which forgets the solver state).
        """
        self.core.safe.forget_solver_state()
        release_free_heap()

    def close(self) -> None:
        self.release_solvers()
