"""``comat bench learn``: decoding speed and end-to-end training throughput.

Two parts:

* **decode**: the autoregressive learners' ``act`` (COMAT's and MAT's) with cached keys/values (one decoder
  step per robot) against ``act_uncached`` (the whole decoder re-run on the prefix for every
  robot), 8 robots, for several batch sizes. Each path's encoder pass is timed on its own and
  subtracted (``act`` encodes with COMAT's compiled encoder, the re-run with torch), so
  ``decode_speedup`` compares the decoding itself; ``act_speedup`` is the whole call.
* **train**: env steps per second of complete training iterations (collect a rollout + learn
  from it, exactly what ``comat train`` runs) for each algorithm on PCP (``tasks``: HMT too) in the unicycle tier
  with the paper's settings, split into time in the environment, in acting and in learning.
  The first iteration (set-ups, caches) is not timed. ``mat_20``, ``mappo_20``, ``qmix_20``: a
  team-sized learner with 20 robot slots (``max_robots: 20``, to play U_scale) instead of 8, on the same
  U_train teams: what the extra slots cost. With ``overlap`` (``--overlap on|both``) a PPO learner
  is also timed with ``ppo.overlap`` (the next rollout collected while the update runs): there the
  iteration's wall time is the update plus the wait for the collection beside it (``wait_s``),
  and the environment's and acting's seconds, spent beside the update, are not split.
* **update**: each PPO learner's update alone on fixed rollouts (one per round, the same teams for
  every learner), the learners taking turns round after round in one process. The training rows
  above time COMAT and MAT minutes apart, and on a shared VM the machine's speed drifts that much
  between them (MAT's unchanged update measured 0.84 s and 1.17 s in two runs minutes apart,
  docs/speed.md); taking turns, both see the same drift, so the median of their ratio is the
  comparison of the learners themselves.
"""

from __future__ import annotations

import copy
import os
import platform
import time

import numpy as np
import torch

from comat.bench.sim_bench import finish
from comat.bench.variants import COMAT_VARIANTS, OVERLAP_CHOICES, WIDE_SLOTS
from comat.learners import learner_entry, learner_names
from comat.models import PAPER_FORM, AutoregressivePolicy, ObsLayout
from comat.rl import Dims, build_modules, load_preset, make_learner, make_run_env, resolve
from comat.tasks import task_names
from comat.tasks.pcp import PCP

__all__ = ["COMAT_VARIANTS", "bench_decode", "bench_train", "bench_update", "run_learn_bench"]

TRAIN_TARGET = 400.0
"""COMAT env-steps/s on PCP, unicycle tier, the learners issue's target for a 2-core machine."""
LEARN_RATIO_TARGET = 1.3
"""COMAT's learning seconds over MAT's in the same run (the same rollout size), at most: the
speed issue's target (issue 48)."""
DECODE_TARGET = 3.0
"""Cached decoding vs a full re-run per robot, 8 robots."""


def _best_time(fn, repeats: int) -> float:
    """Best of ``repeats`` timings of ``fn()`` (s); the minimum is the least noisy estimate."""
    fn()
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


@torch.no_grad()
def bench_decode(model_name: str, n_robots: int = 8, batch: int = 32, repeats: int = 20, seed: int = 0) -> dict:
    """Cached vs uncached autoregressive decoding of learner ``model_name`` ("comat", "mat": an
    autoregressive one, :attr:`comat.learners.LearnerEntry.autoregressive`), its default config."""
    entry = learner_entry(model_name)
    if not entry.autoregressive:
        decoders = [n for n in learner_names() if learner_entry(n).autoregressive]
        raise ValueError(f"bench_decode: model_name must be an autoregressive learner {decoders}, got {model_name!r}")
    torch.manual_seed(seed)
    layout = ObsLayout.for_task(PCP())
    dims = Dims(layout.obs_dim, layout.n_types, layout.n_caps, state_dim=0)  # no state: acting only
    model = build_modules(model_name, dims, entry.config_class()(), acting_only=True)["policy"]
    model.eval()
    obs = torch.randn(batch, n_robots, layout.obs_dim)
    types = torch.randint(0, layout.n_types, (batch, n_robots))
    obs[..., 4 : 4 + layout.n_types] = torch.nn.functional.one_hot(types, layout.n_types).float()
    mask = torch.ones(batch, n_robots, dtype=torch.bool)
    a_cached = model.act(obs, mask, deterministic=True)[0]
    a_uncached = model.act_uncached(obs, mask, deterministic=True)[0]
    if not torch.equal(a_cached, a_uncached):
        raise AssertionError(f"{model_name}: cached and uncached decoding chose different actions")
    # Each path's own encoder is subtracted: act encodes with the compiled kernel where it
    # decodes compiled (COMAT), the re-run reference with the torch encoder.
    t_enc = _best_time(lambda: model.encode(obs, mask), repeats)
    compiled_encoder = (
        model._compiled_ok(obs) and type(model).encode_compiled is not AutoregressivePolicy.encode_compiled
    )
    t_enc_act = _best_time(lambda: model.encode_compiled(obs, mask), repeats) if compiled_encoder else t_enc
    t_cached = _best_time(lambda: model.act(obs, mask, deterministic=True), repeats)
    t_uncached = _best_time(lambda: model.act_uncached(obs, mask, deterministic=True), repeats)
    dec_cached, dec_uncached = max(t_cached - t_enc_act, 1e-9), max(t_uncached - t_enc, 1e-9)
    return {
        "model": model_name,
        "n_robots": n_robots,
        "batch": batch,
        "encode_ms": 1e3 * t_enc,
        "encode_act_ms": 1e3 * t_enc_act,
        "act_cached_ms": 1e3 * t_cached,
        "act_uncached_ms": 1e3 * t_uncached,
        "decode_speedup": dec_uncached / dec_cached,
        "act_speedup": t_uncached / t_cached,
    }


def bench_train(
    algo: str,
    iterations: int = 2,
    env_workers: int = 1,
    preset: str = "paper",
    seed: int = 0,
    task: str = "pcp",
    overlap: bool = False,
) -> dict:
    # long: one timed training, collect and update timers around the loop in one try that closes the env
    """Env-steps/s of ``iterations`` timed training iterations of ``algo`` on ``task`` (unicycle);
    ``comat_paper``: COMAT with the paper-form encoder and decision layer (``PAPER_FORM``), to
    measure what today's default costs against it in the same run; ``comat_<option>``: one option
    of :data:`COMAT_VARIANTS` changed; ``<learner>_20``: that team-sized learner with 20 robot slots;
    ``overlap``: with ``ppo.overlap`` (PPO learners only)."""

    settings = load_preset(preset)
    label, algo = algo, _learner_of(algo)
    variants = {"comat_paper": PAPER_FORM, **COMAT_VARIANTS}
    change = variants.get(label) or ({"max_robots": WIDE_SLOTS} if label != algo else None)
    if change:
        models = dict(settings.get("models") or {})
        models[algo] = {**(models.get(algo) or {}), **change}
        settings = {**settings, "models": models}
    family = learner_entry(algo).family
    if overlap:
        if family != "ppo":
            raise ValueError(f"bench_train: overlap is a PPO option; {algo} has none")
        settings = {**settings, "ppo": {**(settings.get("ppo") or {}), "overlap": True}}
    config = resolve(settings, algo, task, seed=seed, tier="unicycle", env_workers=env_workers)
    torch.set_num_threads(config.torch_threads)
    torch.manual_seed(seed)
    env = make_run_env(config, config.trainer.num_envs, seed)
    try:
        env.reset()
        learner = make_learner(config, env, Dims.of(env))
        clock = {"env": 0.0}

        def timed(call):
            def wrapper(*args, **kwargs):
                t0 = time.perf_counter()
                out = call(*args, **kwargs)
                clock["env"] += time.perf_counter() - t0
                return out

            return wrapper

        # Time spent waiting for the environments: their whole step in one process; with
        # several workers, only what the policy's turn on the other shards did not hide.
        for name in ("step", "step_recv"):
            if hasattr(env, name):
                setattr(env, name, timed(getattr(env, name)))
        learner.iterate()  # warm-up: QP set-ups per team-size tuple, allocator, caches
        steps = collect_s = update_s = env_s = wait_s = 0.0
        for _ in range(iterations):
            clock["env"] = 0.0
            t0 = time.perf_counter()
            if family == "qmix":
                before = learner.trainer.env_steps
                learner.trainer.collect()
                t1 = time.perf_counter()
                learner.trainer.update()
                n = learner.trainer.env_steps - before
                learn = time.perf_counter() - t1
            else:
                rollout, _ = learner.trainer.iterate()
                n = rollout.rewards.numel()
                learn = learner.trainer.timing["update_s"]
                wait_s += learner.trainer.timing.get("wait_s", 0.0)
            steps += n
            update_s += learn
            collect_s += time.perf_counter() - t0 - learn  # overlapped: the wait for the collection beside the update
            env_s += clock["env"]
    finally:
        env.close()
    total = collect_s + update_s
    return {
        "algo": label,
        "overlap": overlap,
        "task": task,
        "tier": "unicycle",
        "num_envs": config.trainer.num_envs,
        "robot_slots": getattr(config.model, "max_robots", None),
        "env_workers": env_workers,
        "torch_threads": config.torch_threads,
        "env_steps": int(steps),
        "env_steps_per_s": steps / total,
        "env_s": None if overlap else env_s,
        "act_s": None if overlap else collect_s - env_s,
        "learn_s": update_s,
        "wait_s": wait_s if overlap else None,
        "env_only_steps_per_s": steps / env_s if env_workers == 1 and not overlap else None,
    }


def bench_update(
    algos, task: str = "pcp", rounds: int = 5, preset: str = "paper", seed: int = 0, env_workers: int = 1
) -> list[dict]:
    """Seconds of one PPO update of each learner in ``algos`` on ``task`` (unicycle), the learners
    taking turns (see the module docstring): each collects ``rounds`` + 1 rollouts with its untrained
    policy (the same teams for every learner: they are drawn from the seed, not by the policy), then
    in round r every learner updates on its own r-th rollout from the same starting state. A rollout
    is one draw of teams, and COMAT's work grows with the robots per team where MAT pads every team
    to its slots (an HMT rollout of 5.4 robots a team against one of 4.7: COMAT/MAT 1.44 against
    1.20), so the rounds cover several draws. The first round is not timed (caches, allocator).
    ``env_workers`` collect the rollouts (not timed; closed before the first update)."""
    setups = {}
    for algo in algos:
        if learner_entry(algo).family != "ppo":
            raise ValueError(f"bench_update: times the PPO learners' update; {algo} has none")
        config = resolve(load_preset(preset), algo, task, seed=seed, tier="unicycle", env_workers=env_workers)
        torch.set_num_threads(config.torch_threads)
        torch.manual_seed(seed)
        env = make_run_env(config, config.trainer.num_envs, seed)
        try:
            env.reset()
            trainer = make_learner(config, env, Dims.of(env)).trainer
            rollouts = [trainer.collect() for _ in range(rounds + 1)]
        finally:
            env.close()
        setups[algo] = (trainer, rollouts, copy.deepcopy(trainer.state_dict()), config.torch_threads)
    seconds: dict[str, list[float]] = {algo: [] for algo in algos}
    for round_ in range(rounds + 1):
        for algo, (trainer, rollouts, state, threads) in setups.items():
            torch.set_num_threads(threads)
            trainer.load_state_dict(copy.deepcopy(state))  # the same weights, optimizer and minibatch order
            t0 = time.perf_counter()
            trainer.update(rollouts[round_])
            if round_:
                seconds[algo].append(time.perf_counter() - t0)
    return [
        {
            "algo": algo,
            "task": task,
            "torch_threads": threads,
            "env_steps": int(rollouts[0].rewards.numel()),
            "robots_per_team": [float(ro.mask.sum(-1).float().mean()) for ro in rollouts[1:]],
            "update_s": seconds[algo],
            "median_s": float(np.median(seconds[algo])) if seconds[algo] else None,
        }
        for algo, (_, rollouts, _, threads) in setups.items()
    ]


def _checks(decode: list[dict], train: list[dict], update: list[dict] = ()) -> dict:
    """Targets: cached decoding >= 3x a full re-run (8 robots; at the rollout batch 32 and at a
    large batch 256), COMAT training >= 400 env-steps/s (best worker count), and COMAT's learning
    seconds <= 1.3x MAT's for each task and worker count both ran (per env step: HMT's rollouts are
    shorter than PCP's, but both learners of a task and worker count collect the same); with the
    update part, the same target on the median over rounds of COMAT's update over MAT's in that
    round (per env step)."""
    checks = {}
    for row in decode:
        if row["batch"] in (32, 256):
            checks[f"{row['model']}_decode_cached_vs_uncached_N8_B{row['batch']}"] = {
                "value": row["decode_speedup"],
                "target": f">= {DECODE_TARGET}",
                "pass": row["decode_speedup"] >= DECODE_TARGET,
            }
    train = [r for r in train if not r["overlap"]]  # the targets are the default's, collect then update
    comat_rows = [r for r in train if r["algo"] == "comat" and r["task"] == "pcp"]
    if comat_rows:
        best = max(comat_rows, key=lambda r: r["env_steps_per_s"])
        checks["comat_train_pcp_unicycle_env_steps_per_s"] = {
            "value": best["env_steps_per_s"],
            "target": f">= {TRAIN_TARGET}",
            "pass": best["env_steps_per_s"] >= TRAIN_TARGET,
            "env_workers": best["env_workers"],
        }
    for comat in (r for r in train if r["algo"] == "comat"):
        for mat in (r for r in train if r["algo"] == "mat"):
            if (mat["task"], mat["env_workers"]) == (comat["task"], comat["env_workers"]):
                ratio = (comat["learn_s"] / comat["env_steps"]) / (mat["learn_s"] / mat["env_steps"])
                checks[f"comat_learn_vs_mat_{comat['task']}_W{comat['env_workers']}"] = {
                    "value": ratio,
                    "target": f"<= {LEARN_RATIO_TARGET}",
                    "pass": ratio <= LEARN_RATIO_TARGET,
                }
    for comat in (r for r in update if r["algo"] == "comat"):
        for mat in (r for r in update if r["algo"] == "mat" and r["task"] == comat["task"]):
            per_round = [
                (c / comat["env_steps"]) / (m / mat["env_steps"]) for c, m in zip(comat["update_s"], mat["update_s"])
            ]
            if per_round:
                ratio = float(np.median(per_round))
                checks[f"comat_update_vs_mat_{comat['task']}"] = {
                    "value": ratio,
                    "target": f"<= {LEARN_RATIO_TARGET}",
                    "pass": ratio <= LEARN_RATIO_TARGET,
                    "rounds": len(per_round),
                }
    return checks


def _family(label: str) -> str:
    """The family of the learner a training row ``label`` times (``comat_paper``, ``mat_20``: COMAT's, MAT's)."""
    return learner_entry(_learner_of(label)).family


def _learner_of(label: str) -> str:
    """The learner a training row ``label`` times: ``comat_paper`` and :data:`COMAT_VARIANTS` are COMAT,
    ``<learner>_20`` that learner."""
    return "comat" if label == "comat_paper" or label in COMAT_VARIANTS else label.removesuffix(f"_{WIDE_SLOTS}")


def run_learn_bench(
    algos=("comat", "comat_paper", "mat", "mappo", "qmix"),
    workers=(1, 2),
    iterations: int = 2,
    batches=(1, 32, 256),
    out: str | None = None,
    progress=print,
    tasks=None,
    overlap: str = "off",
    update_rounds: int = 5,
) -> dict:
    # long: the three parts of the bench and their tables, printed in the order they ran
    """The three parts, a table on ``progress`` and JSON at ``out``; ``overlap``: ``off``, ``on`` (the
    PPO learners with ``ppo.overlap`` only) or ``both`` (each PPO learner both ways, in one run);
    ``update_rounds``: timed rounds of the update part (for the PPO learners among ``algos`` by their
    plain names; 0: no update part)."""
    if overlap not in OVERLAP_CHOICES:
        raise ValueError(f"overlap must be one of {list(OVERLAP_CHOICES)}, got {overlap!r}")
    tasks = task_names() if tasks is None else tuple(tasks)
    decode = []
    for model in (n for n in learner_names() if learner_entry(n).autoregressive):
        for batch in batches:
            progress(f"  decode {model} N=8 B={batch} ...")
            decode.append(bench_decode(model, 8, batch))
    train = []
    ways = {"off": (False,), "on": (True,), "both": (False, True)}[overlap]
    for task in tasks:
        for w in workers:
            for algo in algos:
                for way in ways if _family(algo) == "ppo" else (False,):  # QMIX has no overlap option
                    what = " overlapped" if way else ""
                    progress(f"  train {algo}{what} {task} env_workers={w} ({iterations} iterations) ...")
                    train.append(bench_train(algo, iterations, env_workers=w, task=task, overlap=way))
    update = []
    ppo = [a for a in algos if a in learner_names() and _family(a) == "ppo"]
    for task in tasks if update_rounds > 0 and ppo else ():
        progress(f"  update {', '.join(ppo)} {task}, taking turns ({update_rounds} rounds) ...")
        update += bench_update(ppo, task, update_rounds, env_workers=max(workers))
    checks = _checks(decode, train, update)
    result = {
        "benchmark": "learn",
        "machine": {
            "platform": platform.platform(),
            "python": platform.python_version(),
            "cpus": os.cpu_count(),
            "torch": torch.__version__,
        },
        "decode": decode,
        "train": train,
        "update": update,
        "checks": checks,
    }
    head = (
        f"{'model':<7}{'B':>5}{'encode ms':>11}{'act enc ms':>12}{'cached ms':>11}{'uncached ms':>13}"
        f"{'decode ×':>10}{'act ×':>8}"
    )
    progress(head + "\n" + "-" * len(head))
    for r in decode:
        progress(
            f"{r['model']:<7}{r['batch']:>5}{r['encode_ms']:>11.2f}{r['encode_act_ms']:>12.2f}{r['act_cached_ms']:>11.2f}"
            f"{r['act_uncached_ms']:>13.2f}{r['decode_speedup']:>10.2f}{r['act_speedup']:>8.2f}"
        )
    head = f"{'algo':<17}{'task':>5}{'workers':>8}{'env-steps/s':>13}{'env s':>8}{'act s':>8}{'learn s':>9}"
    head += f"{'wait s':>8}{'env only/s':>12}"
    progress(head + "\n" + "-" * len(head))

    def cell(value, width: int, digits: int = 2) -> str:
        return f"{'-' if value is None else f'{value:.{digits}f}':>{width}}"

    for r in train:
        name = r["algo"] + (" overlapped" if r["overlap"] else "")
        progress(
            f"{name:<17}{r['task']:>5}{r['env_workers']:>8}{r['env_steps_per_s']:>13.1f}"
            f"{cell(r['env_s'], 8)}{cell(r['act_s'], 8)}{cell(r['learn_s'], 9)}{cell(r['wait_s'], 8)}"
            f"{cell(r['env_only_steps_per_s'], 12, 1)}"
        )
    progress(
        "env s: waiting for the environments (with several workers, the part of their steps that the "
        "policy's turns on other shards did not hide); act s: the rest of collecting; overlapped "
        "(ppo.overlap): the collection runs beside the update, wait s is the wait for it after the update."
    )
    if update:
        head = f"{'algo':<17}{'task':>5}{'threads':>8}{'update s (median)':>19}  every round"
        progress(head + "\n" + "-" * len(head))
        for r in update:
            rounds = " ".join(f"{t:.2f}" for t in r["update_s"])
            progress(f"{r['algo']:<17}{r['task']:>5}{r['torch_threads']:>8}{r['median_s']:>19.3f}  {rounds}")
        progress("update: one PPO update on that round's rollout, the learners taking turns in each round.")

    return finish(result, checks, out, progress)
