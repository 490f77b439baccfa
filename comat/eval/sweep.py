"""``comat sweep``: a grid of training runs (algorithms × tasks × seeds) as Ray Tune trials.

A sweep lives in one root folder (``--out``, made absolute before anything reaches a worker)::

    sweep.json                 the sweep's record, written when it starts: its command, the grid,
                               the resolved settings (preset + overrides), evaluation, resources
    <algo>_<task>_s<seed>/     one comat run folder per grid cell, what ``comat train`` writes
                               (+ ``evaluation_<tier>.json``): ``comat report ROOT/*_s*`` reads them;
                               its ``policy.pt`` (the weights to act, small enough to commit) is
                               kept with the small files, so every reported run can be evaluated again
    .tune/                     Ray Tune's experiment state (trial table, per-trial results)
    .aborted/                  what runs stopped before their first checkpoint had written

Every trial trains (or resumes) its run folder from the recorded settings, then evaluates the
final checkpoint on the sets and tiers asked for, as ``comat eval`` would; a finished run without
a ``policy.pt`` (trained before policy files existed) gets one from its checkpoint. A trial whose worker
dies or raises is retried by Tune (``FailureConfig(max_failures)``) and resumes from the run's own
checkpoint, so it computes exactly what an uninterrupted run computes. Jobs start seed-major
(seed 0 of every algorithm and task, then seed 1, ...). Running ``comat sweep
--out ROOT`` again continues the recorded sweep: Tune restores its experiment
(``Tuner.restore``), runs that finished are not started again, interrupted ones resume.

Ray: a local instance by default, or an existing cluster (``address``). Each trial reserves
``max(env_workers, torch_threads)`` CPUs of its run config. On a cluster the driver ships its own
comat code to the workers (``runtime_env`` ``py_modules``), so the nodes need comat's
dependencies but not a checkout; ``ROOT`` must be on storage every node sees at the same path (a
shared file system): workers write the run folders there.
"""

from __future__ import annotations

import csv
import datetime
import itertools
import json
import os
import sys
import time
from pathlib import Path

import comat
import sim2real
from comat.eval.evaluate import evaluate_policies, write_results
from comat.files import portable_command, write_atomic
from comat.learners import learner_names
from comat.rl import (
    DEVICES,
    TASKS,
    apply_overrides,
    ensure_policy,
    load_preset,
    resolve,
    resolve_device,
    train,
    versions,
)
from comat.tasks import task_names

__all__ = ["RECORD", "param_space", "plan", "prepare_sweep", "read_record", "run_job", "run_sweep", "sweep_status"]

RECORD = "sweep.json"
DEFAULTS = {
    "algos": ["comat", "mat", "mappo", "qmix"],
    "tasks": list(task_names()),
    "seeds": None,
    "preset": "paper",
    "steps": None,
    "tier": None,
    "eval_tiers": ["unicycle"],
    "eval_sets": ["train", "test"],
    "episodes": 1,
    "overrides": [],
    "max_failures": 2,
    "device": "auto",
}
"""Settings of a new sweep where none is given (``seeds`` None: the preset's)."""
_PROGRESS_EVERY_S = 30.0


def _job_dir(root: Path, algo: str, task: str, seed: int) -> Path:
    return root / f"{algo}_{task}_s{seed}"


def plan(root: str | Path, algos, tasks, seeds, eval_tiers=("unicycle",), eval_sets=("train", "test")) -> list[dict]:
    """The grid's jobs, each with its state: "done", "resume" or "new"."""
    root = Path(root)
    jobs = []
    for algo, task, seed in itertools.product(algos, tasks, seeds):
        folder = _job_dir(root, algo, task, seed)
        evals_done = all((folder / f"evaluation_{t}.json").is_file() for t in eval_tiers) or not eval_sets
        if (folder / "summary.json").is_file() and evals_done:
            state = "done"
        elif (folder / "checkpoint.pt").is_file():
            state = "resume"
        else:
            state = "new"
        jobs.append({"algo": algo, "task": task, "seed": seed, "folder": str(folder), "state": state})
    return jobs


def read_record(root: str | Path) -> dict | None:
    """The sweep record ``ROOT/sweep.json``, or None where there is none."""
    path = Path(root) / RECORD
    if not path.is_file():
        return None
    try:
        record = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as err:
        raise ValueError(
            f"sweep record {str(path)!r} cannot be read ({err}); expected what comat sweep wrote there"
        ) from err
    if not isinstance(record, dict) or not {"algos", "tasks", "seeds", "settings"} <= set(record):
        raise ValueError(f"sweep record {str(path)!r} is not a comat sweep record (no grid or settings)")
    return record


def _check_grid(algos, tasks, seeds) -> None:

    for name, values, valid in (("algos", algos, learner_names()), ("tasks", tasks, TASKS)):
        bad = [v for v in values if v not in valid]
        if bad or not values:
            raise ValueError(f"--{name} must be a non-empty subset of {list(valid)}, got {list(values)!r}")
    if not seeds or any(isinstance(s, bool) or not isinstance(s, int) or s < 0 for s in seeds):
        raise ValueError(f"--seeds must be non-negative integers, got {list(seeds)!r}")
    if len(set(seeds)) != len(seeds):
        raise ValueError(f"--seeds must not repeat a seed (each names one run folder), got {list(seeds)!r}")


def _cpus_per_trial(settings: dict, algos, tasks, tier, steps) -> int:
    """CPUs one trial reserves: its env processes or its torch threads, whichever is more (the
    learner and the env processes take turns rather than run side by side)."""

    configs = [resolve(settings, a, t, tier=tier, total_env_steps=steps) for a, t in itertools.product(algos, tasks)]
    return max(max(c.env_workers, c.torch_threads) for c in configs)


def prepare_sweep(root: str | Path, given: dict, command: list[str] | None = None) -> tuple[dict, list[str]]:
    """The record of the sweep in ``root``: the one there (``given`` settings must agree with it), or a
    new one from ``given`` and :data:`DEFAULTS`, checked but not yet written. Returns it with the
    lines to tell the user (where the seeds come from; that a recorded sweep continues)."""

    root = Path(os.path.expanduser(str(root))).resolve()
    unknown = sorted(set(given) - set(DEFAULTS))
    if unknown:
        raise ValueError(f"unknown sweep setting(s) {unknown}; valid: {sorted(DEFAULTS)}")
    if root.exists() and not root.is_dir():
        raise ValueError(f"--out {str(root)!r} is a file; expected the sweep's root folder (new or existing)")
    if (root / "config.yaml").is_file():
        raise ValueError(f"--out {str(root)!r} is a run folder of comat train; expected a sweep's root folder")
    old = read_record(root)
    if old is not None:
        differ = [
            f"--{k.replace('_', '-')} {old.get(k)!r} there, {v!r} given"
            for k, v in sorted(given.items())
            if _plain(v) != _plain(old.get(k))
        ]
        if differ:
            raise ValueError(
                f"--out {str(root)!r} holds a sweep with other settings ({'; '.join(differ)}); "
                f"continue it with `comat sweep --out {root}`, or choose another --out"
            )
        jobs = len(old["algos"]) * len(old["tasks"]) * len(old["seeds"])
        return old, [f"continuing the sweep recorded in {root / RECORD} ({jobs} jobs)"]
    spec = {**DEFAULTS, **given}
    settings = apply_overrides(load_preset(spec["preset"]), list(spec["overrides"]))
    preset_seeds = settings.get("seeds") or [0]
    seeds = list(spec["seeds"]) if spec["seeds"] is not None else list(preset_seeds)
    _check_grid(list(spec["algos"]), list(spec["tasks"]), seeds)
    if isinstance(spec["max_failures"], bool) or not isinstance(spec["max_failures"], int) or spec["max_failures"] < 0:
        raise ValueError(f"--retries must be an integer >= 0, got {spec['max_failures']!r}")
    if spec["steps"] is not None and (
        isinstance(spec["steps"], bool) or not isinstance(spec["steps"], int) or spec["steps"] < 1
    ):
        raise ValueError(f"--steps must be an integer >= 1, got {spec['steps']!r}")
    if spec["device"] not in DEVICES:
        raise ValueError(f"--device must be one of {list(DEVICES)}, got {spec['device']!r}")
    if isinstance(spec["episodes"], bool) or not isinstance(spec["episodes"], int) or spec["episodes"] < 1:
        raise ValueError(f"--episodes must be an integer >= 1, got {spec['episodes']!r}")
    cpus = _cpus_per_trial(settings, spec["algos"], spec["tasks"], spec["tier"], spec["steps"])  # checks the preset
    origin = (
        f"seeds {seeds} from --seeds (the preset's: {list(preset_seeds)})"
        if spec["seeds"] is not None
        else f"seeds {seeds} from the preset {spec['preset']!r} (--seeds changes them)"
    )
    record = {
        "format": 1,
        "command": list(command or sys.argv),
        "cwd": os.getcwd(),
        "root": str(root),
        "started": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        **{k: _plain(spec[k]) for k in DEFAULTS if k != "seeds"},
        "seeds": seeds,
        "seeds_from": "--seeds" if spec["seeds"] is not None else "preset",
        "settings": settings,
        "cpus_per_trial": cpus,
        # The driver's code and commit: on a cluster the workers run this code from Ray's copy,
        # outside any git checkout, so their config.yaml cannot name the commit.
        "versions": versions(),
    }
    return record, [origin]


def _plain(value):
    """Tuples as lists, as a record read back from JSON has them."""
    return [_plain(v) for v in value] if isinstance(value, (list, tuple)) else value


def _trained(folder: Path) -> tuple[int, float]:
    """(env steps, wall s) of a run's last progress row (0, 0.0 without one)."""
    path = folder / "progress.csv"
    if not path.is_file():
        return 0, 0.0
    with path.open(newline="") as f:
        rows = list(csv.DictReader(f))
    return (int(rows[-1]["env_steps"]), float(rows[-1]["wall_s"])) if rows else (0, 0.0)


def sweep_status(root: str | Path, record: dict) -> list[dict]:
    """Where each job of the recorded grid stands, without running anything.

    Per job: its :func:`plan` state, env steps trained of the budget, its rate (env steps per
    second of its own training so far) and the hours left at that rate — or, for a job not
    started, at the mean rate of the grid's other runs of the same task (None if there is none).
    Evaluation time is not included.
    """

    rows = []
    for job in plan(root, record["algos"], record["tasks"], record["seeds"], record["eval_tiers"], record["eval_sets"]):
        total = resolve(
            record["settings"],
            job["algo"],
            job["task"],
            seed=job["seed"],
            tier=record["tier"],
            total_env_steps=record["steps"],
        ).total_env_steps
        done, wall = _trained(Path(job["folder"]))
        rate = done / wall if done and wall > 0 else None
        rows.append({**job, "env_steps": done, "total_env_steps": total, "env_steps_per_s": rate})
    for row in rows:
        rate = row["env_steps_per_s"]
        if rate is None:
            same = [r["env_steps_per_s"] for r in rows if r["task"] == row["task"] and r["env_steps_per_s"]]
            rate = sum(same) / len(same) if same else None
        left = 0 if row["state"] == "done" else max(row["total_env_steps"] - row["env_steps"], 0)
        row["hours_left"] = 0.0 if left == 0 else (left / rate / 3600 if rate else None)
    return rows


def _set_aside_partial(folder: Path) -> None:
    """A run stopped before its first checkpoint cannot resume: move what it wrote to
    ``<root>/.aborted/<name>-<k>`` (kept, out of report globs) so the job can start over."""
    if (folder / "checkpoint.pt").is_file() or not folder.is_dir() or not any(folder.iterdir()):
        return
    aside = folder.parent / ".aborted"
    aside.mkdir(exist_ok=True)
    k = 1 + sum(1 for p in aside.glob(f"{folder.name}-*"))
    folder.rename(aside / f"{folder.name}-{k}")


def run_job(params: dict) -> dict:
    """One grid cell, as a Ray Tune function trainable: train (or resume) the run folder, then
    evaluate it; reports progress to Tune after every update. ``params``: ``job`` (its ``algo``,
    ``task`` and ``seed``) and ``sweep`` (the record)."""
    from ray import tune

    record = params["sweep"]
    algo, task, seed = params["job"]["algo"], params["job"]["task"], params["job"]["seed"]
    folder = _job_dir(Path(record["root"]), algo, task, seed)
    t0 = time.perf_counter()
    config = resolve(
        record["settings"],
        algo,
        task,
        seed=seed,
        tier=record["tier"],
        total_env_steps=record["steps"],
        device=record["device_resolved"],
    )
    eval_sets = record["eval_sets"]
    if plan(record["root"], [algo], [task], [seed], record["eval_tiers"], eval_sets)[0]["state"] == "done":
        ensure_policy(folder)
        tune.report({"env_steps": 0, "skipped": True, "done": True})
        return {}
    _set_aside_partial(folder)
    resume = (folder / "checkpoint.pt").is_file()
    summary = train(
        config,
        folder,
        resume=resume,
        quiet=True,
        overrides=tuple(record["overrides"]),
        command=portable_command(record["command"], record.get("cwd")),  # as typed where it ran
        on_update=lambda p: tune.report(
            {
                "env_steps": p["env_steps"],
                "wall_s": p["wall_s"],
                "checkpoint_env_steps": p["checkpoint_env_steps"],
                "done": False,
            }
        ),
    )
    for eval_tier in record["eval_tiers"] if eval_sets else ():
        if not (folder / f"evaluation_{eval_tier}.json").is_file():
            result = evaluate_policies(
                folder / "checkpoint.pt",
                task,
                tuple(eval_sets),
                record["episodes"],
                eval_tier,
                references=False,
                progress=lambda _m: None,
            )
            write_results(result, folder, f"evaluation_{eval_tier}")
    tune.report(
        {
            "env_steps": summary["env_steps"],
            "wall_s": summary["wall_s"],
            "resumed": resume,
            "job_wall_s": time.perf_counter() - t0,
            "done": True,
        }
    )
    return {}


def param_space(record: dict) -> dict:
    """Tune's search space of a sweep: one grid axis of jobs, seed-major (Tune would otherwise vary
    the algo/task/seed keys in alphabetical order, all seeds of one algorithm first), so that a
    sweep stopped early holds seed 0 of every algorithm and task."""
    from ray import tune

    jobs = [
        {"algo": a, "task": t, "seed": s}
        for s, t, a in itertools.product(record["seeds"], record["tasks"], record["algos"])
    ]
    return {"job": tune.grid_search(jobs), "sweep": record}


def _reporter(progress, total_steps: dict):
    """A Tune callback that prints a line per job when it starts, every 30 s of its progress,
    when it is retried and when it ends."""
    from ray.tune import Callback

    class Lines(Callback):
        def __init__(self):
            self.last: dict[str, float] = {}

        @staticmethod
        def _name(trial) -> str:
            c = trial.config["job"]
            return f"{c['algo']}/{c['task']}/s{c['seed']}"

        def on_trial_start(self, iteration, trials, trial, **info):
            progress(f"  started {self._name(trial)}")

        def on_trial_result(self, iteration, trials, trial, result, **info):
            key, now = self._name(trial), time.monotonic()
            if result.get("done") or now - self.last.get(key, -1e9) < _PROGRESS_EVERY_S:
                return
            self.last[key] = now
            total = total_steps[(trial.config["job"]["algo"], trial.config["job"]["task"])]
            rate = result["env_steps"] / result["wall_s"] if result.get("wall_s") else 0.0
            progress(
                f"  {key}: {result['env_steps']:,} / {total:,} env steps ({rate:.0f}/s), checkpoint at "
                f"{result.get('checkpoint_env_steps') or 0:,}"
            )

        def on_trial_recover(self, iteration, trials, trial, **info):
            progress(
                f"  RETRY {self._name(trial)}: its worker failed ({trial.num_failures} failure(s)); it resumes "
                "from its checkpoint"
            )

        def on_trial_complete(self, iteration, trials, trial, **info):
            r = trial.last_result or {}
            what = "already done" if r.get("skipped") else f"{r.get('env_steps', 0):,} env steps"
            progress(f"  done {self._name(trial)}: {what}")

        def on_trial_error(self, iteration, trials, trial, **info):
            progress(
                f"  FAILED {self._name(trial)} after {trial.num_failures} failure(s); its folder keeps what it "
                "wrote (run the sweep again to resume it)"
            )

    return Lines()


def _code() -> list[str]:
    """The packages shipped to cluster workers: the driver's own comat (and sim2real, which export
    and evaluation import), so every node runs the code that planned the sweep. Folders, not module
    objects: inside a ``ray job submit`` job Ray merges this with the job's runtime env by pickling it."""

    return [str(Path(m.__file__).parent) for m in (comat, sim2real)]


def _write_record(root: Path, record: dict) -> None:
    """Create the root folder and write the record, once (a continued sweep keeps its first one)."""

    try:
        root.mkdir(parents=True, exist_ok=True)
        if not (root / RECORD).is_file():
            write_atomic(root / RECORD, json.dumps(record, indent=2))
    except OSError as err:
        raise ValueError(
            f"--out {str(root)!r} cannot be written ({err.strerror or err}); expected a folder this "
            "user can create and write"
        ) from err


def _cluster_device(name: str) -> str:
    """``--device`` on a cluster: auto is cuda where the cluster has a GPU; cuda needs one."""
    import ray

    gpus = ray.cluster_resources().get("GPU", 0)
    if name == "cuda" and gpus < 1:
        raise ValueError("--device cuda: the Ray cluster has no GPU; use --device cpu or auto")
    return "cuda" if name == "cuda" or (name == "auto" and gpus >= 1) else "cpu"


def run_sweep(record: dict, address: str | None = None, jobs: int | None = None, progress=print) -> list[dict]:
    """Write the record (a new sweep) and run its unfinished jobs on Ray Tune; returns one
    :func:`plan` row per job, with ``error`` for those that did not finish."""
    # Tune's own table would repeat what the callback below prints, one line per job.
    os.environ.setdefault("RAY_AIR_NEW_OUTPUT", "0")
    if address is None:
        # A local instance talks over loopback only: Ray would otherwise replace 127.0.0.1 with this
        # machine's network address (it reads this when ray is first imported).
        os.environ.setdefault("RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER", "0")
    try:
        import ray
        from ray import tune
    except ImportError as err:
        raise ValueError(
            f"comat sweep runs on Ray Tune, which cannot be imported here ({err}); install it with "
            "pip install 'comat[ray]'"
        ) from err

    root = Path(record["root"])
    grid = (record["algos"], record["tasks"], record["seeds"], record["eval_tiers"], record["eval_sets"])
    jobs_now = plan(root, *grid)
    todo = [j for j in jobs_now if j["state"] != "done"]
    if (root / RECORD).is_file() and not todo:
        for job in jobs_now:  # finished before policy files existed: keep theirs now
            ensure_policy(job["folder"])
        progress(f"comat sweep: {len(jobs_now)} jobs, all finished, in {root}")
        return jobs_now
    cpus = record["cpus_per_trial"]
    if address is None:
        record = {**record, "device_resolved": record.get("device_resolved") or resolve_device(record["device"])}
        _write_record(root, record)  # before Ray starts: an unwritable --out fails at once
        ray.init(num_cpus=None if jobs is None else jobs * cpus, include_dashboard=False, log_to_driver=False)
    else:
        # A cluster's workers get the driver's code, not whatever their node has installed.
        ray.init(address=address, log_to_driver=False, runtime_env={"py_modules": _code(), "excludes": ["__pycache__"]})
    try:
        if address is not None:
            record = {**record, "device_resolved": record.get("device_resolved") or _cluster_device(record["device"])}
            _write_record(root, record)
        progress(
            f"comat sweep: {len(jobs_now)} jobs, {len(jobs_now) - len(todo)} finished, {len(todo)} to run "
            f"({sum(j['state'] == 'resume' for j in todo)} resumed), {cpus} CPU(s) each, updates on "
            f"{record['device_resolved']}, in {root}"
        )
        totals = {
            (a, t): resolve(
                record["settings"], a, t, tier=record["tier"], total_env_steps=record["steps"]
            ).total_env_steps
            for a, t in itertools.product(record["algos"], record["tasks"])
        }
        gpus = 1 if record["device_resolved"] == "cuda" else 0
        trainable = tune.with_resources(run_job, {"cpu": cpus, "gpu": gpus})
        run_config = tune.RunConfig(
            name=".tune",
            storage_path=str(root),
            verbose=0,
            failure_config=tune.FailureConfig(max_failures=record["max_failures"]),
            callbacks=[_reporter(progress, totals)],
        )
        experiment = root / ".tune"
        if tune.Tuner.can_restore(str(experiment)):
            tuner = tune.Tuner.restore(str(experiment), trainable, resume_unfinished=True, restart_errored=True)
        else:
            tuner = tune.Tuner(
                trainable,
                run_config=run_config,
                tune_config=tune.TuneConfig(max_concurrent_trials=jobs),
                param_space=param_space(record),
            )
        results = tuner.fit()
        errors = {tuple(r.config["job"][k] for k in ("algo", "task", "seed")): r.error for r in results if r.error}
    finally:
        ray.shutdown()
    rows = plan(root, *grid)
    for row in rows:
        err = errors.get((row["algo"], row["task"], row["seed"]))
        if err is not None or row["state"] != "done":
            row["error"] = repr(err) if err is not None else "not finished"
    return rows
