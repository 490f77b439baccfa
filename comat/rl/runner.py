"""A training run from start to finish: folder, loop, evaluation, checkpoints, resume.

Run folder (``--out``)::

    config.yaml      the resolved RunConfig, versions and the command line (written first; a resumed
                     run keeps those of its earlier sittings under ``earlier_sittings``)
    checkpoint.pt    latest checkpoint (atomic), every ``checkpoint_every_steps`` and at the end
    policy.pt        the final policy: the weights to act and their config, no optimizer state
                     (:mod:`comat.rl.policy`; small enough to commit), written when the run finishes
    progress.csv     one row per update: env steps, wall time, env-steps/s, episode metrics, losses
    eval.csv         one row per evaluation on the training coalitions (deterministic actions)
    eval_SET.csv     the same evaluations on each set of ``eval_sets`` (none by default)
    policy_N.pt      the policy at the first update reaching each of ``keep_policies_at`` (none by default)
    tb/              TensorBoard events of both tables
    rrd/             Rerun recordings of evaluation episodes (``rrd_every``), ``eval_<env steps>.rrd``
    summary.json     the final evaluation, written when the run finishes

``train(..., resume=True)`` continues from ``checkpoint.pt``: weights, optimizer, normalizers,
replay buffer, every random generator and the env-step counter are restored, and every
rollout starts from freshly reset environments, so the resumed run takes exactly the updates
the uninterrupted run would have taken. A folder holding a ``policy.pt`` but no checkpoint
(a finished run's committed files) cannot be resumed, nor trained into again.
"""

from __future__ import annotations

import json
import sys
import time
from collections.abc import Callable
from pathlib import Path

import torch

from comat.envs.base import resolve_coalitions
from comat.envs.outside import is_outside, play_outside
from comat.files import portable_command, write_atomic
from comat.machine import RunRegistry, busy_warning, usable_cpus
from comat.measure.episodes import run_episodes, summarize
from comat.rl.algos import Dims, make_learner, make_run_env, policy_act
from comat.rl.checkpoint import CheckpointError, load_checkpoint, save_checkpoint, versions
from comat.rl.config import RunConfig
from comat.rl.logger import ExpectedTime, ProgressLine, RunLogger
from comat.rl.policy import POLICY_FILE, save_policy

__all__ = ["EVAL_SEED_OFFSET", "Recorder", "train"]

EVAL_SEED_OFFSET = 1_000_003

Recorder = Callable[[RunConfig, dict, Path, int], tuple[Path, str]]
"""``record(config, modules, out, env_steps) -> (path, how to view it)``: records evaluation episodes
of the modules being trained (:func:`comat.viz.record_training`)."""
"""Evaluation episodes use seed ``run seed + EVAL_SEED_OFFSET`` (never a training seed)."""
_SUMMARY_KEYS = ("return", "steps", "progress", "finished", "coordination", "collisions", "interventions", "fallbacks")
"""Episode metrics logged per update in progress.csv and TensorBoard (a task without a coordination
metric logs NaN there; a run resumed from an older progress.csv keeps its own columns)."""


def _write_config(
    out: Path,
    config: RunConfig,
    resumed_at: int | None,
    overrides: tuple[str, ...] = (),
    command: list[str] | None = None,
) -> None:
    """``config.yaml``: the resolved config, versions (the source's commit among them) and command
    line of this sitting (no absolute paths: :func:`comat.files.portable_command`); a
    resumed run keeps those of its earlier sittings under ``earlier_sittings`` (which code trained what)."""
    import yaml

    doc = {
        "config": config.to_dict(),
        "versions": versions(),
        "command": portable_command(command or sys.argv),
        "overrides": list(overrides),
        "resumed_at_env_steps": resumed_at,
    }
    path = out / "config.yaml"
    if resumed_at is not None and path.is_file():
        old = yaml.safe_load(path.read_text()) or {}
        sitting = {k: old.get(k) for k in ("versions", "command", "overrides", "resumed_at_env_steps")}
        doc["earlier_sittings"] = [*old.get("earlier_sittings", []), sitting]
    write_atomic(path, yaml.safe_dump(doc, sort_keys=False))


def evaluate(config: RunConfig, modules: dict, episodes_per_team: int | None = None, coalitions=None) -> dict:
    """Mean metrics of the deterministic policy, ``episodes_per_team`` episodes per coalition (of
    ``coalitions``, default the run's training teams), at the run's reality layer (what the run
    trains under; ``comat eval --reality`` for others). An outside task (:mod:`comat.envs.outside`)
    plays ``episodes_per_team`` episodes of its one team: its return and steps (no progress)."""
    seed, act = config.seed + EVAL_SEED_OFFSET, policy_act(config.algo, modules)
    count = episodes_per_team or config.eval_episodes_per_team
    if is_outside(config.task):  # one team, its own
        teams, env = None, make_run_env(config, min(count, 32), seed)
    else:
        coalitions = config.coalitions if coalitions is None else coalitions
        teams = resolve_coalitions(coalitions, config.task) * count
        env = make_run_env(config, min(len(teams), 32), seed, coalitions)
    for m in modules.values():
        m.eval()
    try:
        episodes = play_outside(env, act, count, seed) if teams is None else run_episodes(env, act, teams, seed)
    finally:
        env.close()
        for m in modules.values():
            m.train()
    return summarize(episodes)


def saved_config(out: str | Path) -> RunConfig | None:
    """The run config in ``out/config.yaml`` (what a run stopped before its first checkpoint left),
    or None where there is none or it cannot be read."""
    import yaml

    try:
        return RunConfig.from_dict(yaml.safe_load((Path(out) / "config.yaml").read_text())["config"])
    except (OSError, KeyError, TypeError, ValueError, yaml.YAMLError):
        return None


def _restarting(out: Path, config: RunConfig) -> bool:
    """Whether ``out``'s config.yaml (a run without a checkpoint yet) is this config's run."""
    saved = saved_config(out)
    return saved is not None and saved.to_dict() == config.to_dict()


def _weights(learner) -> dict:
    """The learner's networks' state dicts, by name (what a policy file keeps)."""
    return {name: m.state_dict() for name, m in learner.modules.items()}


def _next_multiple(steps: int, every: int) -> int:
    return (steps // every + 1) * every


def train(
    config: RunConfig,
    out: str | Path,
    resume: bool = False,
    quiet: bool = False,
    rrd_every: int = 0,
    overrides: tuple[str, ...] = (),
    command: list[str] | None = None,
    on_update=None,
    record: Recorder | None = None,
) -> dict:
    # long: checks a run folder's every state (new, resumed, finished, policy-only) before the loop starts
    """Train (or, with ``resume``, continue) the run in folder ``out``; returns a summary with
    the final evaluation on the training coalitions (None if evaluation is off). A finished run
    (or a finished one resumed) writes ``out/policy.pt`` (:func:`comat.rl.policy.save_policy`).

    ``overrides``: the ``key=value`` changes to the preset that ``config`` was resolved with,
    recorded in config.yaml next to the resolved config (they are already part of it).
    ``rrd_every`` = K > 0 records two evaluation episodes to ``out/rrd/`` at every K-th
    evaluation and the last (a viewing aid; not part of the run's identity) with ``record``
    (:func:`comat.viz.record_training`, which ``comat train --rrd-every`` passes: the recorder
    lives above the trainer, so it is handed in rather than imported).
    ``command``: the command line recorded in config.yaml (default ``sys.argv``; a sweep job
    records the ``comat sweep`` command, not its worker's). ``on_update(progress)`` is called after
    every update with ``env_steps``, ``updates``, ``wall_s`` and ``checkpoint_env_steps`` (how a
    sweep shows progress while its jobs run).

    Raises:
        FileExistsError: ``out`` already holds a run and ``resume`` is False (nothing is touched).
        CheckpointError: ``resume`` without a usable checkpoint for this algo and task (a folder
            with a policy.pt but no checkpoint.pt included).
    """
    out = Path(out)
    ckpt_path = out / "checkpoint.pt"
    data = None
    if (out / POLICY_FILE).is_file() and not ckpt_path.exists():
        # Not a run stopped early: a finished one whose checkpoint is gone (e.g. its committed files).
        raise (CheckpointError if resume else FileExistsError)(
            f"{str(out)!r} holds a finished run's {POLICY_FILE} but no checkpoint.pt: "
            + (
                "a policy file keeps the weights to act, not the optimizer, normalizers, buffers or generators a "
                "run resumes from"
                if resume
                else "it is not trained into again"
            )
            + "; train a new run in another --out"
        )
    if resume and not ckpt_path.exists() and (out / "config.yaml").is_file():
        # Killed before its first checkpoint: nothing to continue, so the run starts over.
        resume = False
        if not quiet:
            print(
                f"{str(out)!r} has no checkpoint yet (stopped before the first one): starting it from step 0",
                file=sys.stderr,
            )
    elif resume:
        data = load_checkpoint(ckpt_path, algo=config.algo, task=config.task)
        saved = RunConfig.from_dict(data["config"])
        # Neither the step budget, the policies kept along it nor MuJoCo's thread count changes what
        # the run computes.
        free = ("total_env_steps", "physics_threads", "keep_policies_at")
        if {k: v for k, v in saved.to_dict().items() if k not in free} != {
            k: v for k, v in config.to_dict().items() if k not in free
        }:
            raise CheckpointError(
                f"checkpoint {str(ckpt_path)!r} was written with another configuration; "
                "resume it with its own (see config.yaml), or start a new run in another --out"
            )
    if isinstance(rrd_every, bool) or not isinstance(rrd_every, int) or rrd_every < 0:
        raise ValueError(f"rrd_every must be an integer >= 0 (every K-th evaluation; 0 = never), got {rrd_every!r}")
    if rrd_every and record is None:
        raise ValueError(
            "rrd_every needs record= (comat.viz.record_training): the trainer does not import the recorder"
        )
    if rrd_every and not config.eval_episodes_per_team:
        raise ValueError("rrd_every records evaluation episodes, but this run's eval_episodes_per_team is 0")
    if not resume and data is None and ckpt_path.exists():
        raise FileExistsError(
            f"{str(out)!r} already holds a run; pass --resume to continue it, or choose another --out"
        )
    if not resume and (out / "config.yaml").exists() and not ckpt_path.exists() and not _restarting(out, config):
        raise FileExistsError(
            f"{str(out)!r} already holds a run (stopped before its first checkpoint) with another "
            "configuration; pass --resume to start that run over, or choose another --out"
        )
    out.mkdir(parents=True, exist_ok=True)
    for stale in out.glob(f".{ckpt_path.name}.*.tmp"):  # left by a kill during a checkpoint write
        stale.unlink()
    with RunRegistry(out, config.torch_threads) as others:  # who else trains here, for the warning
        warning = busy_warning(others, usable_cpus())
        if warning and not quiet:
            print(warning, file=sys.stderr)
        threads = torch.get_num_threads()
        try:
            return _train_registered(
                config, out, data, quiet, rrd_every, overrides, command, ckpt_path, on_update, record
            )
        finally:  # the run's torch_threads stay the run's: an in-process caller (a test, a notebook)
            torch.set_num_threads(threads)  # would otherwise run on them after it (a spinning thread)


def _train_registered(
    config: RunConfig,
    out: Path,
    data: dict | None,
    quiet: bool,
    rrd_every: int,
    overrides: tuple[str, ...],
    command: list[str] | None,
    ckpt_path: Path,
    on_update,
    record: Recorder | None,
) -> dict:
    # long: the training loop: eval, checkpoint and logging share the loop's progress counters
    """The training loop of :func:`train`, once the run is checked and registered."""
    torch.set_num_threads(config.torch_threads)
    torch.manual_seed(config.seed)
    env = make_run_env(config, config.trainer.num_envs, config.seed)
    env.reset()
    dims = Dims.of(env)
    learner = make_learner(config, env, dims)
    progress = {"env_steps": 0, "updates": 0, "wall_s": 0.0}
    if data is not None:
        learner.load_state_dict(data["trainer"])
        env.set_rng_state(data["env_rngs"])
        torch.set_rng_state(data["torch_rng"])
        progress = dict(data["progress"])
    _write_config(out, config, progress["env_steps"] if data is not None else None, tuple(overrides), command)
    logger = RunLogger(out, resume_step=progress["env_steps"] if data is not None else None)
    if learner.family == "ppo" and not quiet:
        per = config.trainer.num_envs * (config.trainer.rollout_steps or env.task.horizon)
        if config.total_env_steps % per:
            print(
                f"note: PPO trains in whole rollouts of {per:,} env steps ({config.trainer.num_envs} environments × "
                f"{per // config.trainer.num_envs} steps): {config.total_env_steps:,} env steps run as "
                f"{-(-config.total_env_steps // per) * per:,}",
                file=sys.stderr,
            )
    bar = None if quiet else ProgressLine(config.total_env_steps, start=progress["env_steps"])
    expected = ExpectedTime(
        config.total_env_steps,
        progress["env_steps"],
        config.env_workers,
        config.torch_threads,
        overlap=config.overlap,
    )
    started = time.perf_counter()
    next_eval = _next_multiple(progress["env_steps"], config.eval_every_steps)
    next_ckpt = _next_multiple(progress["env_steps"], config.checkpoint_every_steps)
    last_eval: dict | None = None

    def checkpoint() -> None:
        save_checkpoint(
            ckpt_path,
            algo=config.algo,
            task=config.task,
            config=config.to_dict(),
            progress={**progress, "dims": dims.to_dict()},
            trainer=learner.state_dict(),
            env_rngs=env.rng_state(),
        )

    recent: list[dict] = []
    saved_at = progress["env_steps"] if data is not None else None
    kept = {t for t in config.keep_policies_at if t <= progress["env_steps"]}  # written before that checkpoint
    try:
        while progress["env_steps"] < config.total_env_steps:
            t0 = time.perf_counter()
            learner.set_progress(progress["env_steps"] / config.total_env_steps)
            episodes, stats, n = learner.iterate()
            dt = time.perf_counter() - t0
            progress["env_steps"] += n
            progress["updates"] += 1
            progress["wall_s"] += dt
            recent = (recent + episodes)[-200:]
            ep = summarize(episodes) if episodes else {}
            row = {
                "updates": progress["updates"],
                "wall_s": round(progress["wall_s"], 3),
                "env_steps_per_s": n / dt,
                "episodes": len(episodes),
                **{f"episode_{k}": ep.get(k, float("nan")) for k in _SUMMARY_KEYS},
                **stats,
            }
            logger.log("progress", progress["env_steps"], row)
            steps = progress["env_steps"]
            said = expected.expected(steps, n, dt, time.perf_counter() - started)
            if said and not quiet and steps < config.total_env_steps:
                print(("\n" if bar is not None and bar.tty else "") + said, file=sys.stderr)
            finished = steps >= config.total_env_steps
            if bar is not None and recent:
                tail = summarize(recent[-64:])
                bar.update(steps, tail["return"], tail["finished"], tail["progress"], final=finished)
            if config.eval_episodes_per_team and (steps >= next_eval or finished):
                last_eval = evaluate(config, learner.modules)
                logger.log("eval", steps, last_eval)
                for name in config.eval_sets:  # budget curves on other sets: eval_<set>.csv
                    logger.log(f"eval_{name}", steps, evaluate(config, learner.modules, coalitions=name))
                next_eval = _next_multiple(steps, config.eval_every_steps)
                evals = steps // config.eval_every_steps
                if rrd_every and (evals % rrd_every == 0 or finished):
                    rrd, hint = record(config, learner.modules, out, steps)
                    if not quiet:
                        print(f"\nrecorded {rrd}; {hint}", file=sys.stderr)
                if not quiet:
                    print(
                        f"\neval @ {steps:,} steps: return {last_eval['return']:.2f}, finished "
                        f"{last_eval['finished']:.0%} (progress {last_eval['progress']:.0%}), "
                        f"steps {last_eval['steps']:.1f}, collisions "
                        f"{last_eval['collisions']:.2f}",
                        file=sys.stderr,
                    )
            for target in [t for t in config.keep_policies_at if t <= steps and t not in kept]:
                # before the checkpoint of this update: a resumed run has every file its checkpoint passed
                save_policy(out / f"policy_{target}.pt", config, dims, _weights(learner), progress)
                kept.add(target)
            if steps >= next_ckpt or finished:
                checkpoint()
                saved_at = steps
                next_ckpt = _next_multiple(steps, config.checkpoint_every_steps)
            if on_update is not None:
                on_update({**progress, "checkpoint_env_steps": saved_at})
    finally:
        logger.close()
        env.close()
    if last_eval is None and config.eval_episodes_per_team:  # resumed a run that had already finished
        last_eval = evaluate(config, learner.modules)
    # The policy to keep, from the weights the final checkpoint holds (before summary.json, which
    # marks the run finished).
    save_policy(out / POLICY_FILE, config, dims, _weights(learner), progress)
    summary = {
        "algo": config.algo,
        "task": config.task,
        "seed": config.seed,
        "tier": config.tier,
        "env_steps": progress["env_steps"],
        "wall_s": progress["wall_s"],
        "eval_train": last_eval,
    }
    write_atomic(out / "summary.json", json.dumps(summary, indent=2))
    return summary
