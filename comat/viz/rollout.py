"""Rollouts to ``.rrd`` files: run a policy for some episodes and record every one of them.

``record_episodes(path, task, policy, ...)`` checks everything first — the output path (folder
exists, is writable, name ends in ``.rrd``), the policy (``"heuristic"``, ``"random"``, a
callable, or a checkpoint whose task must match), the episode count — and only then runs.
The file is written next to its target under a temporary name and renamed into place when
complete, so a failed rollout never leaves a half-written ``.rrd`` behind.

Policies take the evaluation convention ``act(obs (B, N, D), mask (B, N), state (B, S) or
None) -> actions (B, N)`` with B = 1 here (:mod:`comat.measure.episodes`). The scripted heuristic
reads the environment's task state (privileged; :mod:`comat.envs.heuristics`); ``"random"``
draws uniform actions from a generator seeded by the rollout seed.

Episode k starts from ``reset(seed=seed + k)``: with ``teams``, episode k runs ``teams[k]``;
otherwise its team is drawn from the coalition set by that seed.
"""

from __future__ import annotations

import hashlib
import os
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import rerun as rr

from comat.config import REFERENCE_TIER
from comat.envs import make_env
from comat.envs.base import resolve_coalitions
from comat.envs.heuristics import LADDER, RUNG_ALIASES, reference_policy
from comat.rl import EVAL_SEED_OFFSET, RunConfig, load_policy, policy_act, robot_slots, shipped_name
from comat.tasks import env_id, task_names
from comat.team import COALITION_SETS, TeamSpec
from comat.viz.blueprint import rollout_blueprint
from comat.viz.recorder import EpisodeRecorder
from comat.viz.video import VideoWriter, check_video_path
from comat.viz.viewer import viewer_hint

__all__ = [
    "POLICY_NAMES",
    "PolicySpec",
    "RolloutResult",
    "check_rrd_path",
    "play_episodes",
    "record_episodes",
    "record_training",
    "resolve_policy",
]

POLICY_NAMES = (*LADDER, *RUNG_ALIASES)
"""Built-in policies (the reference ladder, :mod:`comat.envs.heuristics`); any other ``--policy`` value is a
checkpoint path. The type_only rung believes U_train's type means here (a rollout's team may come from any set)."""
TASKS = task_names()

Act = Callable[[np.ndarray, np.ndarray, "np.ndarray | None"], np.ndarray]


@dataclass(frozen=True)
class PolicySpec:
    """A policy ready to bind to an environment.

    Attributes:
        name: what the recording calls it (``heuristic``, ``random``, ``comat checkpoint …``).
        bind: ``bind(env, seed) -> act`` for a freshly made :class:`comat.envs.TaskEnv`.
        use_state: act needs the centralized state (MAPPO).
        max_robots: robot slots the policy expects (None: any).
        tier: the dynamics tier it was trained on (None: no preference).
    """

    name: str
    bind: Callable[[Any, int], Act]
    use_state: bool = False
    max_robots: int | None = None
    tier: str | None = None


@dataclass
class RolloutResult:
    """What a rollout produced: the file, each episode's metrics, sizes and timing.

    Attributes:
        recorder_cpu_s: CPU seconds the recording took on the rollout's own thread (scene,
            per-tick taps, per-step buffers, sending, opening and closing the file).
        background_cpu_s: CPU seconds of the process's other threads meanwhile (Rerun's
            encoder and file writer; the simulation itself runs on one thread).
    """

    path: Path | None
    episodes: list[dict[str, float]] = field(default_factory=list)
    steps: int = 0
    robot_steps: int = 0
    bytes: int = 0
    wall_s: float = 0.0
    recorder_cpu_s: float = 0.0
    background_cpu_s: float = 0.0
    video: Path | None = None

    @property
    def bytes_per_robot_step(self) -> float:
        return self.bytes / max(self.robot_steps, 1)


def resolve_policy(policy: str | Path | Act, task: str) -> PolicySpec:
    """A :class:`PolicySpec` from a rung of the reference ladder (``"heuristic"``, ``"type_only"``, ``"blind"``,
    ``"constant"``, ``"random"``), a checkpoint path or a callable.

    Raises:
        ValueError: an unknown name that is no file either, or a checkpoint for another task
            (:class:`comat.rl.checkpoint.CheckpointError`).
    """
    if task not in TASKS:
        raise ValueError(f"task must be one of {TASKS}, got {task!r}")
    if callable(policy):
        return PolicySpec(getattr(policy, "__name__", "policy"), lambda env, seed: policy)
    if not isinstance(policy, (str, Path)):
        raise TypeError(
            f"policy must be one of {POLICY_NAMES}, a checkpoint path or a callable, got {type(policy).__name__}"
        )
    if str(policy) in POLICY_NAMES:
        name = RUNG_ALIASES.get(str(policy), str(policy))
        return PolicySpec(name, lambda env, seed: reference_policy(name, env.core, seed))
    if not Path(policy).is_file():
        why = "a folder; expected a checkpoint.pt file" if Path(policy).is_dir() else "no such file"
        raise ValueError(f"policy must be one of {POLICY_NAMES} or a checkpoint file, got {str(policy)!r} ({why})")
    act, config = load_policy(policy, task=task)  # CheckpointError (a ValueError) names a task mismatch
    shipped = shipped_name(policy)
    kind = "policy" if Path(policy).name.startswith("policy") else "checkpoint"
    return PolicySpec(
        shipped if shipped else f"{config.algo} {kind} {Path(policy).name}",  # the shipped name says the learner
        lambda env, seed: act,
        max_robots=robot_slots(config),
        tier=config.tier,
    )


def check_rrd_path(path: str | Path, flag: str = "out", folder: bool = True) -> Path:
    """``path`` as a Path once it is known that an ``.rrd`` file can be written there.

    ``folder=False``: only the name checks (its folder is to be created, e.g. by ``--out``).

    Raises:
        ValueError: naming the path and what is wrong: not ``.rrd``, a folder, a missing
            folder, a parent that is a file, or a folder where no file can be created.
    """
    p = Path(path)
    if p.suffix != ".rrd":
        raise ValueError(f"{flag} must be a file name ending in .rrd, got {str(p)!r}")
    if p.is_dir():
        raise ValueError(f"{flag} must be a file, got {str(p)!r}, which is a folder")
    if not folder:
        return p
    parent = p.parent
    if not parent.exists():
        raise ValueError(f"{flag}: folder {str(parent)!r} does not exist (create it first), got {str(p)!r}")
    if not parent.is_dir():
        raise ValueError(f"{flag}: {str(parent)!r} is not a folder, got {str(p)!r}")
    try:  # permissions, read-only mounts, quotas: only trying tells
        fd, probe = tempfile.mkstemp(prefix=f".{p.name}.", suffix=".probe", dir=parent)
        os.close(fd)
        os.unlink(probe)
    except OSError as err:
        raise ValueError(f"{flag}: cannot write in folder {str(parent)!r} ({err.strerror}), got {str(p)!r}") from err
    if p.exists() and not os.access(p, os.W_OK):
        raise ValueError(f"{flag}: {str(p)!r} exists and is not writable")
    return p


def _check_count(name: str, value: Any) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise ValueError(f"{name} must be a positive integer, got {value!r}")
    return int(value)


def frame_caption(policy: str, n_robots: int, seed: int, episode: int, episodes: int) -> str:
    """A video frame's first header line: the most telling first, as a caption too long for the room
    left of the coordination metric is cut at its end (the policy, the team's size, the episode's
    seed; the episode's index only when there are several)."""
    return f"{policy} · {n_robots} robots · seed {seed}" + (f" · episode {episode}" if episodes > 1 else "")


def play_episodes(
    env,
    act: Act,
    recorder: EpisodeRecorder,
    *,
    episodes: int,
    seed: int,
    use_state: bool = False,
    teams: Sequence[TeamSpec] | None = None,
    metadata: dict[str, Any] | None = None,
    on_frame: Callable[[np.ndarray], None] | None = None,
) -> list[dict]:
    """Run ``episodes`` episodes of a :class:`comat.envs.TaskEnv`, each one recorded by ``recorder``
    (a disabled recorder records nothing); returns each episode's metrics plus ``team_size``.

    ``on_frame``: called with ``env.render()`` (an env made with ``render_mode="rgb_array"``)
    after every reset and every step: T + 1 frames for an episode of T steps."""
    core = env.core
    results = []
    for k in range(episodes):
        options = {"team": teams[k]} if teams is not None else None
        env.reset(seed=seed + k, options=options)
        recorder.begin(core, 0, episode=k, metadata={**(metadata or {}), "seed": seed + k, "team_size": env.team.size})
        n = env.team.size
        if on_frame is not None:
            env.render_caption = frame_caption((metadata or {}).get("policy", ""), n, seed + k, k, episodes)
            on_frame(env.render())
        metrics: dict[str, float] = {}
        while env.agents:
            actions = np.asarray(act(core.observe(), core.mask, core.global_state() if use_state else None))[0, :n]
            _, rewards, _, _, infos = env.step({a: int(actions[i]) for i, a in enumerate(env.agents)})
            info = infos["robot_0"]
            recorder.step(actions, rewards["robot_0"], {t: info[f"reward/{t}"] for t in core.task.reward_terms})
            if on_frame is not None:
                on_frame(env.render())
            if not env.agents:
                metrics = {k_[len("episode/") :]: v for k_, v in info.items() if k_.startswith("episode/")}
        recorder.end(metrics)
        results.append({**metrics, "team_size": n})
    return results


def _checked_teams(task: str, teams, episodes: int | None, coalitions) -> tuple[list[TeamSpec] | None, int]:
    """``(teams as a list or None, episodes)``: given teams are TeamSpecs of ``task``, at least one
    per episode (``episodes`` defaults to one per given team, else 1); ``coalitions`` a set's name or teams."""
    if teams is not None:
        teams = list(teams)
        if not teams or not all(isinstance(t, TeamSpec) for t in teams):
            raise ValueError(f"teams must be a non-empty list of TeamSpec, got {teams!r:.200}")
        wrong = [i for i, t in enumerate(teams) if t.task != task]
        if wrong:
            raise ValueError(f"teams[{wrong[0]}] is a {teams[wrong[0]].task!r} team, but the rollout runs {task!r}")
    episodes = _check_count("episodes", episodes if episodes is not None else len(teams) if teams else 1)
    if teams is not None and len(teams) < episodes:
        raise ValueError(f"teams must list at least one team per episode ({episodes}), got {len(teams)}")
    if isinstance(coalitions, str) and coalitions not in COALITION_SETS:
        raise ValueError(f"coalitions must be one of {list(COALITION_SETS)} or a list of teams, got {coalitions!r}")
    return teams, episodes


def _recording_stream(out: Path, task: str, name: str, policy, seed: int) -> rr.RecordingStream:
    """The Rerun stream of a rollout to ``out`` by the policy ``name`` (``policy`` as given), its id
    unique per file, task, policy file and seed, and its data free of wall-clock times."""
    # Two runs' checkpoints share a file name (checkpoint.pt): the id names the file by its
    # full path, so recordings of different runs never merge in the viewer.
    source = name
    if isinstance(policy, (str, Path)) and Path(policy).is_file():
        source += "-" + hashlib.sha1(str(Path(policy).resolve()).encode()).hexdigest()[:10]
    rec = rr.RecordingStream("comat", recording_id=f"{out.stem}-{task}-{source}-seed{seed}")
    # Content, not wall-clock ticks: the same rollout gives the same data.
    rec.set_log_time_enabled(False)
    rec.set_log_tick_enabled(False)
    return rec


def _rollout_env(task: str, spec: PolicySpec, pool, tier, max_robots, ticks_per_step, frames: bool, reality):
    """The env a rollout plays: ``pool`` (teams or a set's name) at ``tier`` (default the policy's,
    else the reference tier), with the policy's robot slots (``max_robots`` overrides them; the
    largest team must fit), drawing RGB frames if ``frames``."""
    tier = tier or spec.tier or REFERENCE_TIER
    slots = max_robots if max_robots is not None else spec.max_robots
    largest = max(t.size for t in resolve_coalitions(pool, task))
    if slots is not None and largest > slots:
        raise ValueError(
            f"teams of up to {largest} robots do not fit the policy's {slots} robot slots (a fixed-size "
            f"{spec.name}: train it with models.<algo>.max_robots={largest} or more)"
        )
    return make_env(
        env_id(task),
        coalitions=pool,
        tier=tier,
        ticks_per_step=ticks_per_step,
        max_robots=slots,
        state_robots=slots or 8,  # a baseline's centralized state covers all its slots
        render_mode="rgb_array" if frames else None,
        reality=reality,
    )


def record_episodes(
    path: str | Path | None,
    task: str,
    policy: str | Path | Act | PolicySpec = "heuristic",
    *,
    episodes: int | None = None,
    teams: Sequence[TeamSpec] | None = None,
    coalitions: str | Sequence[TeamSpec] = "train",
    seed: int = 0,
    tier: str | None = None,
    ticks_per_step: int | None = None,
    use_state: bool | None = None,
    max_robots: int | None = None,
    policy_name: str | None = None,
    video: str | Path | None = None,
    fps: int = 10,
    reality: Any = "off",
) -> RolloutResult:
    # long: a 23-line docstring of its options, then one try closing writer, temp file and timers together
    """Run and record episodes of ``task`` (a registered task's name: ``comat tasks``) to the ``.rrd`` file ``path``.

    Args:
        path: output file; None runs the same episodes without recording (benchmarks).
        policy: "heuristic", "random", a checkpoint path, an ``act`` callable, or a PolicySpec.
        episodes: how many (default: one per entry of ``teams``, else 1).
        teams: the team of each episode (else drawn from ``coalitions``: "train", "test", "scale" or
            a list of teams).
        seed: episode k resets with ``seed + k``.
        tier: dynamics tier (default: the checkpoint's, else :data:`comat.config.REFERENCE_TIER`).
        ticks_per_step: control ticks per env step (default: the task's).
        use_state, max_robots: override what the policy declares (a trainer's own policy).
        policy_name: how the recording names the policy.
        video: also (or, with ``path`` None, only) write the episodes as a ``.mp4`` or ``.gif``
            of ``env.render()`` frames (:mod:`comat.viz.video`), ``fps`` frames per second, one
            frame per env step and one at each start.
        reality: the reality layer the episodes play at (:func:`comat.reality.resolve_reality`);
            recordings and videos then show each robot's measured pose next to its true one
            and mark faulty motors.

    Returns:
        A :class:`RolloutResult`; the file holds one recording, each episode under ``episode_<k>/``.
    """
    out = None if path is None else check_rrd_path(path)
    if video is not None:
        video = check_video_path(video)
    spec = policy if isinstance(policy, PolicySpec) else resolve_policy(policy, task)
    teams, episodes = _checked_teams(task, teams, episodes, coalitions)
    # Given teams are the env's whole set: its robot slots fit the largest of them.
    pool = teams if teams is not None else coalitions
    env = _rollout_env(task, spec, pool, tier, max_robots, ticks_per_step, video is not None, reality)
    act = spec.bind(env, seed)
    meta = {
        "policy": policy_name or spec.name,
        "reality": env.core.reality_config.label,
        "coalition set": "given teams"
        if teams is not None
        else coalitions
        if isinstance(coalitions, str)
        else f"{len(coalitions)} teams given",
    }
    state = spec.use_state if use_state is None else use_state
    rec = tmp = writer = None
    t0, thread0, others0 = time.perf_counter(), time.thread_time(), time.process_time() - time.thread_time()
    if out is not None:
        tmp = out.with_name(f".{out.name}.{os.getpid()}.tmp")
        rec = _recording_stream(out, task, spec.name, policy, seed)
    try:
        if rec is not None:
            rec.save(tmp, default_blueprint=rollout_blueprint(range(episodes)))
        file_cpu = time.thread_time() - thread0
        recorder = EpisodeRecorder(rec)
        writer = None if video is None else VideoWriter(video, fps)
        results = play_episodes(
            env,
            act,
            recorder,
            episodes=episodes,
            seed=seed,
            use_state=state,
            teams=teams,
            metadata=meta,
            on_frame=None if writer is None else writer.append,
        )
        if writer is not None:
            writer.close()
        if rec is not None:
            thread1 = time.thread_time()
            rec.disconnect()  # writes the footer: the file is complete only now
            os.replace(tmp, out)
            file_cpu += time.thread_time() - thread1
    except BaseException:
        if writer is not None:
            writer.abort()
        if rec is not None:
            rec.disconnect()
            tmp.unlink(missing_ok=True)
        raise
    result = _result(out, results, time.perf_counter() - t0)
    result.video = video
    if rec is not None:
        result.recorder_cpu_s = file_cpu + recorder.cpu_s
        result.background_cpu_s = time.process_time() - time.thread_time() - others0
    return result


def _result(path: Path | None, episodes: list[dict], wall_s: float) -> RolloutResult:
    steps = int(sum(e["steps"] for e in episodes))
    robot_steps = int(sum(e["steps"] * e["team_size"] for e in episodes))
    size = path.stat().st_size if path is not None else 0
    return RolloutResult(path, episodes, steps, robot_steps, size, wall_s)


def record_training(config: RunConfig, modules: dict, out: Path, steps: int, episodes: int = 2) -> tuple[Path, str]:
    """Record ``episodes`` evaluation episodes of a run being trained (the first training coalitions)
    to ``out/rrd/eval_<env steps>.rrd``; returns the file and how to view it. The recorder that
    :func:`comat.rl.runner.train` calls with ``rrd_every``."""
    path = out / "rrd" / f"eval_{steps:012d}.rrd"
    path.parent.mkdir(parents=True, exist_ok=True)
    for m in modules.values():
        m.eval()
    try:
        record_episodes(
            path,
            config.task,
            policy_act(config.algo, modules),
            teams=resolve_coalitions("train", config.task)[:episodes],
            seed=config.seed + EVAL_SEED_OFFSET,
            tier=config.tier,
            max_robots=robot_slots(config),
            reality=config.reality,
            policy_name=f"{config.algo} after {steps:,} env steps",
        )
    finally:
        for m in modules.values():
            m.train()
    return path, viewer_hint(path)
