"""``comat sweep``: a grid of training runs (algorithms × tasks × seeds) as Ray jobs.

Every job is one run folder ``<root>/<algo>_<task>_s<seed>``: train (or resume) it, then
evaluate the final checkpoint on the sets and tiers asked for (``evaluation_<tier>.json``, as
``comat eval`` writes it). A job whose folder already has ``summary.json`` and every requested
evaluation is skipped; one with a checkpoint but no summary is resumed; one stopped before its
first checkpoint is set aside (``<root>/.aborted/``) and started over. So a sweep can be
stopped at any moment and re-run with the same command to finish it. A job that fails (or
whose worker dies) is reported and the others go on; the sweep then exits non-zero.

Ray: a local instance by default (``num_cpus`` = the jobs run at once, each job one CPU), or an
existing cluster with ``address`` (``"auto"`` or ``ray://host:10001``); the run folders must
then be on storage every node sees.
"""

from __future__ import annotations

import csv
import itertools
import time
from pathlib import Path

__all__ = ["Job", "plan", "run_job", "run_sweep", "sweep_status"]


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


Job = dict
"""One grid cell: ``algo``, ``task``, ``seed``, ``folder``, ``state``."""


def _trained(folder: Path) -> tuple[int, float]:
    """(env steps, wall s) of a run's last progress row (0, 0.0 without one)."""
    path = folder / "progress.csv"
    if not path.is_file():
        return 0, 0.0
    with path.open(newline="") as f:
        rows = list(csv.DictReader(f))
    return (int(rows[-1]["env_steps"]), float(rows[-1]["wall_s"])) if rows else (0, 0.0)


def sweep_status(root: str | Path, algos, tasks, seeds, preset: str = "paper", steps: int | None = None,
                 tier: str | None = None, eval_tiers=("unicycle",), eval_sets=("train", "test"),
                 overrides: tuple[str, ...] = ()) -> list[dict]:
    """Where each job of the grid stands, without running anything.

    Per job: its :func:`plan` state, env steps trained of the budget, its rate (env steps per
    second of its own training so far) and the hours left at that rate — or, for a job not
    started, at the mean rate of the grid's other runs of the same task (None if there is none).
    Evaluation time is not included.
    """
    from comat.rl.config import apply_overrides, load_preset, resolve

    settings = apply_overrides(load_preset(preset), overrides)
    rows = []
    for job in plan(root, algos, tasks, seeds, eval_tiers, eval_sets):
        total = resolve(settings, job["algo"], job["task"], seed=job["seed"], tier=tier,
                        total_env_steps=steps).total_env_steps
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


def run_job(job: Job, preset: str, steps: int | None, tier: str | None, eval_tiers, eval_sets, episodes: int,
            env_workers: int | None = None, overrides: tuple[str, ...] = ()) -> dict:
    """Train (or resume) one run and evaluate it; returns a short summary. Runs in a Ray worker."""
    import torch

    from comat.eval.evaluate import evaluate_policies, write_results
    from comat.rl.config import apply_overrides, load_preset, resolve
    from comat.rl.runner import train

    torch.set_num_threads(1)
    folder = Path(job["folder"])
    t0 = time.perf_counter()
    _set_aside_partial(folder)
    config = resolve(apply_overrides(load_preset(preset), overrides), job["algo"], job["task"], seed=job["seed"],
                     tier=tier, total_env_steps=steps, env_workers=env_workers)
    resume = (folder / "checkpoint.pt").is_file()
    summary = train(config, folder, resume=resume, quiet=True, overrides=tuple(overrides))
    for eval_tier in eval_tiers if eval_sets else ():
        if not (folder / f"evaluation_{eval_tier}.json").is_file():
            result = evaluate_policies(folder / "checkpoint.pt", job["task"], tuple(eval_sets), episodes, eval_tier,
                                       references=False, progress=lambda _m: None)
            write_results(result, folder, f"evaluation_{eval_tier}")
    return {**{k: job[k] for k in ("algo", "task", "seed", "folder")}, "resumed": resume,
            "env_steps": summary["env_steps"], "wall_s": time.perf_counter() - t0}


def run_sweep(root: str | Path, algos, tasks, seeds, preset: str = "paper", steps: int | None = None,
              tier: str | None = None, eval_tiers=("unicycle",), eval_sets=("train", "test"), episodes: int = 1,
              address: str | None = None, num_cpus: int | None = None, progress=print,
              overrides: tuple[str, ...] = ()) -> list[dict]:
    """Run the grid's unfinished jobs on Ray; returns one record per job (skipped ones too)."""
    import ray

    from comat.rl.config import ALGOS, TASKS, apply_overrides, load_preset, resolve

    for name, values, valid in (("algos", algos, ALGOS), ("tasks", tasks, TASKS)):
        bad = [v for v in values if v not in valid]
        if bad or not values:
            raise ValueError(f"{name} must be a non-empty subset of {list(valid)}, got {list(values)!r}")
    if not seeds or any(isinstance(s, bool) or not isinstance(s, int) or s < 0 for s in seeds):
        raise ValueError(f"seeds must be non-negative integers, got {list(seeds)!r}")
    for algo, task in itertools.product(algos, tasks):  # bad presets fail here, before Ray starts
        resolve(apply_overrides(load_preset(preset), overrides), algo, task, seed=seeds[0], tier=tier,
                total_env_steps=steps)
    root = Path(root)
    root.mkdir(parents=True, exist_ok=True)
    jobs = plan(root, algos, tasks, seeds, eval_tiers, eval_sets)
    records = [{**j, "skipped": True} for j in jobs if j["state"] == "done"]
    todo = [j for j in jobs if j["state"] != "done"]
    progress(f"comat sweep: {len(jobs)} jobs, {len(records)} finished (skipped), {len(todo)} to run "
             f"({sum(j['state'] == 'resume' for j in todo)} resumed) in {root}")
    if not todo:
        return records
    if address is None:
        ray.init(num_cpus=num_cpus, include_dashboard=False, log_to_driver=False, ignore_reinit_error=True)
    else:
        ray.init(address=address, log_to_driver=False, ignore_reinit_error=True)
    try:
        remote = ray.remote(num_cpus=1, max_retries=0)(run_job)
        pending = {remote.remote(j, preset, steps, tier, tuple(eval_tiers), tuple(eval_sets), episodes, None,
                                 tuple(overrides)): j for j in todo}
        while pending:
            ready, _ = ray.wait(list(pending), num_returns=1)
            job = pending.pop(ready[0])
            try:
                rec = ray.get(ready[0])
                progress(f"  done {job['algo']}/{job['task']}/s{job['seed']}: {rec['env_steps']:,} env steps in "
                         f"{rec['wall_s'] / 60:.1f} min ({len(pending)} left)")
                records.append({**rec, "skipped": False})
            except ray.exceptions.RayError as exc:  # the job raised, or its worker died
                cause = getattr(exc, "cause", None) or exc
                progress(f"  FAILED {job['algo']}/{job['task']}/s{job['seed']}: {cause!r:.300} (its folder keeps "
                         "what it wrote; re-run the sweep to resume it)")
                records.append({**job, "skipped": False, "error": repr(cause)})
    finally:
        if address is None:
            ray.shutdown()
    return records
