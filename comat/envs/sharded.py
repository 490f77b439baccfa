"""A :class:`VectorEnv` split over worker processes: the same interface, more cores.

``ShardedVectorEnv(env_id, num_envs, workers=k, seed=s, **options)`` runs environments
``[a_i, b_i)`` in worker i (an ordinary ``VectorEnv`` with ``shard=(a_i, num_envs)``), so every
environment draws its teams and starts from the same seed stream as in one ``VectorEnv`` of
``num_envs``. Per step the actions (B, N) are split, the workers step in parallel and the
results are concatenated back in environment order. ``step_send(i, …)`` / ``step_recv(i)`` step
one worker's environments asynchronously, so a trainer can compute one shard's next actions
while the others simulate (:meth:`comat.rl.ppo.PPOTrainer.collect` does).

Results are deterministic for a given ``workers``; they equal the single-process env's up to
the safety QP's tolerance, not bit for bit (each worker solves one QP for its own teams, and
OSQP's stopping rule looks at the whole problem).

Workers are started with the ``spawn`` method (safe with torch and MuJoCo threads) and stop
when :meth:`close` is called, when the object is garbage-collected, or with the parent.
"""

from __future__ import annotations

import itertools
import multiprocessing as mp
import traceback
from typing import Any, Self

import numpy as np

from comat.envs.registry import check_options, make_local_vec_env, make_task
from comat.team import TeamSpec

__all__ = ["ShardedVectorEnv", "WorkerError", "shard_slices"]


class WorkerError(RuntimeError):
    """An environment worker failed; the message carries its traceback."""


def shard_slices(num_envs: int, workers: int) -> list[slice]:
    """The environments each worker process holds: contiguous, near-equal slices in order."""
    bounds = np.linspace(0, num_envs, workers + 1).round().astype(int)
    return [slice(int(a), int(b)) for a, b in itertools.pairwise(bounds)]


def _worker(conn, env_id: str, num_envs: int, first: int, total: int, seed: int, options: dict) -> None:

    try:
        env = make_local_vec_env(env_id, num_envs, seed=seed, shard=(first, total), **options)
    except BaseException as exc:  # noqa: BLE001 - reported to the parent, which raises
        conn.send(("error", exc, traceback.format_exc()))
        return
    conn.send(("ok", (env.max_robots, env.state_size()), None))
    while True:
        try:
            cmd, arg = conn.recv()
        except EOFError:
            return
        if cmd == "close":
            conn.close()
            return
        try:
            if cmd == "step":
                result = env.step(arg)
            elif cmd == "step_state":
                result = (*env.step(arg), env.state())
            elif cmd == "reset":
                result = env.reset(*arg)
            elif cmd == "state":
                result = env.state()
            elif cmd == "rng_state":
                result = env.rng_state()
            elif cmd == "set_rng_state":
                result = env.set_rng_state(arg)
            elif cmd == "teams":
                result = env.teams()
            elif cmd == "release_solvers":
                result = env.release_solvers()
            else:
                raise ValueError(f"unknown worker command {cmd!r}")
            conn.send(("ok", result, None))
        except Exception as exc:  # noqa: BLE001 - the same exception is raised in the parent
            conn.send(("error", exc, traceback.format_exc()))


class ShardedVectorEnv:
    """``num_envs`` environments of ``env_id`` stepped by ``workers`` processes.

    Args:
        env_id: ``"pcp_v0"`` or ``"hmt_v0"``.
        num_envs: B, split as evenly as possible over the workers.
        workers: worker processes (1 … B).
        seed: as for :class:`comat.envs.VectorEnv` (None: fresh entropy, shared by all workers).
        **options: env options (see :class:`comat.envs.base.TaskEnv`).
    """

    def __init__(self, env_id: str, num_envs: int, *, workers: int, seed: int | None = None, **options: Any) -> None:

        check_options(env_id, options, vector=True)
        if isinstance(num_envs, bool) or not isinstance(num_envs, int) or num_envs < 1:
            raise ValueError(f"num_envs must be a positive integer, got {num_envs!r}")
        if isinstance(workers, bool) or not isinstance(workers, int) or not 1 <= workers <= num_envs:
            raise ValueError(f"workers must be an integer in [1, num_envs={num_envs}], got {workers!r}")
        self.num_envs, self.workers = num_envs, workers
        self.task = make_task(env_id, options)[0]
        seed = int(np.random.SeedSequence().entropy) if seed is None else seed
        self._slices = shard_slices(num_envs, workers)
        ctx = mp.get_context("spawn")
        self._conns, self._procs = [], []
        for sl in self._slices:
            parent, child = ctx.Pipe()
            proc = ctx.Process(
                target=_worker, daemon=True, args=(child, env_id, sl.stop - sl.start, sl.start, num_envs, seed, options)
            )
            proc.start()
            child.close()
            self._conns.append(parent)
            self._procs.append(proc)
        self._closed = False
        shapes = self._gather()
        self.max_robots, self._state_size = shapes[0]
        from gymnasium import spaces

        self.single_observation_space = spaces.Box(-np.inf, np.inf, (self.task.obs_size(),), np.float64)
        self.single_action_space = spaces.Discrete(5)
        self._mask = np.zeros((num_envs, self.max_robots), dtype=bool)

    # -- plumbing ---------------------------------------------------------------------------------
    def _recv(self, i: int) -> Any:
        try:
            status, value, trace = self._conns[i].recv()
        except EOFError:
            self.close()
            raise WorkerError(f"environment worker {i} exited unexpectedly") from None
        if status == "error":
            self.close()
            if isinstance(value, (ValueError, TypeError)):
                raise value  # bad input: the same error as from a single-process env
            raise WorkerError(f"environment worker {i} failed:\n{trace}")
        return value

    def _gather(self) -> list[Any]:
        return [self._recv(i) for i in range(len(self._conns))]

    def _call(self, cmd: str, args: list[Any] | None = None) -> list[Any]:
        if self._closed:
            raise RuntimeError("the environment is closed")
        for i, conn in enumerate(self._conns):
            conn.send((cmd, None if args is None else args[i]))
        return self._gather()

    # -- VectorEnv interface ----------------------------------------------------------------------
    @property
    def agent_mask(self) -> np.ndarray:
        """(B, N) True where a slot holds a robot of the current team."""
        return self._mask.copy()

    def reset(self, seed: int | None = None, teams: list[TeamSpec] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        """As :meth:`comat.envs.VectorEnv.reset`."""
        if teams is not None and (len(teams) != self.num_envs or not all(isinstance(t, TeamSpec) for t in teams)):
            raise ValueError(
                f"teams must be a list of {self.num_envs} TeamSpec (one per environment), got {teams!r:.200}"
            )
        results = self._call("reset", [(seed, None if teams is None else teams[sl]) for sl in self._slices])
        obs = np.concatenate([r[0] for r in results])
        info = _merge_infos([r[1] for r in results], [r[0] for r in results], self._state_size)
        self._mask = info["agent_mask"]
        return obs, info

    def step(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """As :meth:`comat.envs.VectorEnv.step` (the same arrays and info keys)."""
        actions = np.asarray(actions)
        if actions.shape != (self.num_envs, self.max_robots):
            raise ValueError(
                f"actions must have shape ({self.num_envs}, {self.max_robots}) (envs, robot slots), got {actions.shape}"
            )
        results = self._call("step", [actions[sl] for sl in self._slices])
        obs = np.concatenate([r[0] for r in results])
        rewards, terminated, truncated = (np.concatenate([r[k] for r in results]) for k in (1, 2, 3))
        info = _merge_infos([r[4] for r in results], [r[0] for r in results], self._state_size)
        self._mask = info["agent_mask"]
        return obs, rewards, terminated, truncated, info

    # -- one shard at a time (overlapping the policy with the other shards' physics) ---------------
    @property
    def slices(self) -> list[slice]:
        """The environments of each worker (see :func:`shard_slices`)."""
        return list(self._slices)

    def step_send(self, i: int, actions: np.ndarray, with_state: bool = False) -> None:
        """Start worker ``i``'s env step with its actions (n_i, N); :meth:`step_recv` collects it.

        Other workers may be sent their step before this one is collected: that is how a
        trainer computes the next actions of one shard while the others simulate.
        """
        if self._closed:
            raise RuntimeError("the environment is closed")
        sl = self._slices[i]
        actions = np.asarray(actions)
        if actions.shape != (sl.stop - sl.start, self.max_robots):
            raise ValueError(
                f"actions of worker {i} must have shape ({sl.stop - sl.start}, {self.max_robots}) "
                f"(its envs, robot slots), got {actions.shape}"
            )
        self._conns[i].send(("step_state" if with_state else "step", actions))

    def step_recv(self, i: int) -> tuple:
        """Worker ``i``'s step results, as :meth:`step` returns them for its environments only
        (plus its (n_i, S) states when sent ``with_state``)."""
        result = self._recv(i)
        self._mask[self._slices[i]] = result[4]["agent_mask"]
        return result

    def state(self) -> np.ndarray:
        """(B, S) centralized states."""
        return np.concatenate(self._call("state"))

    def state_size(self) -> int:
        """S, the length of :meth:`state` rows."""
        return self._state_size

    def teams(self) -> list[TeamSpec]:
        """The current team of every environment."""
        return [t for part in self._call("teams") for t in part]

    def rng_state(self) -> list[dict]:
        """The environments' generator states, in environment order (for checkpoints)."""
        return [s for part in self._call("rng_state") for s in part]

    def set_rng_state(self, states: list[dict]) -> None:
        """Restore generator states from :meth:`rng_state`."""
        if len(states) != self.num_envs:
            raise ValueError(f"expected {self.num_envs} generator states (one per environment), got {len(states)}")
        self._call("set_rng_state", [states[sl] for sl in self._slices])

    def release_solvers(self) -> None:
        """Every worker drops its OSQP problems (see :meth:`comat.envs.VectorEnv.release_solvers`)."""
        self._call("release_solvers")

    def close(self) -> None:
        """Stop the workers (idempotent)."""
        if getattr(self, "_closed", True):
            return
        self._closed = True
        for conn in self._conns:
            try:
                conn.send(("close", None))
            except (BrokenPipeError, OSError):
                pass
        for proc in self._procs:
            proc.join(timeout=5)
            if proc.is_alive():
                proc.terminate()

    def __del__(self) -> None:
        self.close()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _merge_infos(infos: list[dict], obs: list[np.ndarray], state_size: int) -> dict[str, Any]:
    """Concatenate the workers' infos in environment order; episode keys are filled for
    workers whose environments did not finish (``_episode`` False there)."""
    merged = {
        k: np.concatenate([i[k] for i in infos])
        for k in infos[0]
        if k in ("agent_mask", "type_ids") or k.startswith("reward/")
    }
    if not any("_episode" in i for i in infos):
        return merged
    sizes = [len(o) for o in obs]
    merged["_episode"] = np.concatenate([i.get("_episode", np.zeros(n, bool)) for i, n in zip(infos, sizes)])
    merged["final_obs"] = np.concatenate([i.get("final_obs", o) for i, o in zip(infos, obs)])
    ref = next(i for i in infos if "_episode" in i)  # a worker with a finished episode: the shapes

    def filled(get) -> np.ndarray:
        """One episode array over all workers: zeros, shaped like ``ref``'s, where none finished."""
        return np.concatenate(
            [get(i) if "_episode" in i else np.zeros((n, *get(ref).shape[1:])) for i, n in zip(infos, sizes)]
        )

    merged["episode_curve"] = filled(lambda i: i["episode_curve"])
    for key in ("episode", "episode_robots", "episode_end"):
        merged[key] = {name: filled(lambda i, k=key, m=name: i[k][m]) for name in ref[key]}
    if all("final_state" in i for i in infos if "_episode" in i):
        merged["final_state"] = np.concatenate(
            [i.get("final_state", np.zeros((n, state_size))) for i, n in zip(infos, sizes)]
        )
    return merged
