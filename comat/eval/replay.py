"""A real run beside its simulated twin, and its plant scored: ``comat replay LOG --export DIR``.

The run's log (:mod:`comat.runlog`: what the exported ``main.py`` saw and did on the Robotarium, or
under ``rps`` standing in for it) is laid next to its **twin**: the same team, prey and policy run
closed-loop in comat's MuJoCo world (:func:`sim2real.check.mujoco_twin`) at a reality level or a
calibrated profile, **from the poses the run logged first** (where the robots really started; the
layer's start error is then off) and for as many env steps as the run was allowed. Both are
compared at every env step's start, like with like: the poses the real script received against
those the twin's script saw. What it writes:

* a **gap table** (Markdown and CSV): steps, return, progress, finished, and the position
  divergence's mean, 95th percentile and maximum over steps; with ``--open-loop`` the divergence of
  the logged commands played through the profile's plant from the logged first pose
  (:func:`comat.eval.plant.open_loop`, mean over its draws);
* a **sim-to-sim baseline**: the same divergence between two twins that differ only in the layer's
  seed, i.e. what a model that is exactly right would still show (0 at ``off``: its twin is
  deterministic);
* the **k-step prediction error** of each profile given (``--reality`` and ``--profiles``) on this
  log (:func:`comat.eval.plant.kstep_errors`): per robot and in total, for k = 1, 5, 30 ticks, with
  the score that ranks the profiles (CSV ``<stem>_kstep.csv``);
* with ``--envelope N`` (N >= 20) an **envelope**: N twins under the profile's randomness (seeds
  ``seed … seed + N - 1``), the real outcome's percentile among them per task metric, and the real
  divergence's percentile among the twins' divergences from the first twin (CSV
  ``<stem>_envelope.csv``);
* a Rerun recording (robots labelled with id and type) and, with ``--video``, a top-down video with
  the task's objects (:mod:`comat.eval.replay_draw`).

How to read the divergence: :data:`READING` (printed under the tables).

The twin must be the run's: the export folder's weights have the sha256 the log records and its
team, start poses and prey are the log's (else one line says which differs).
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from comat import constants as C
from comat.eval.plant import DRAWS, KSTEP_TICKS, PlantError, check_horizons, kstep_errors, open_loop
from comat.eval.replay_draw import record
from comat.eval.replay_draw import video as draw_video
from comat.files import csv_text, write_atomic
from comat.reality import resolve_reality
from comat.runlog import RunLog, read_run_log
from sim2real.check import mujoco_twin
from sim2real.export import layout_of, load_config

__all__ = [
    "ENVELOPE_MIN_RUNS",
    "GAP_METRICS",
    "READING",
    "ReplayError",
    "check_options",
    "check_twin",
    "deployed_loop_of",
    "gap_rows",
    "output_names",
    "replay",
    "step_poses",
    "twin_steps",
]

GAP_METRICS = ("steps", "return", "progress", "finished")
"""Task metrics the gap table puts side by side (the real run's from its log's result)."""
ENVELOPE_MIN_RUNS = 20
"""The fewest twins an envelope takes: with 20, a real outcome outside all of them is below the 2.5th
or above the 97.5th percentile."""
READING = (
    "Reading the divergence: the closed-loop divergence mixes two things, the plant (how the robots "
    "move for the commands they get) and the policy's choices (one different waypoint and the runs part "
    "ways for good). Even a twin that is exactly right diverges from the run it models, by about the "
    "sim-to-sim baseline; a real divergence at or below that line says nothing against the profile, one "
    "well above it says the twin is off, but not where. To judge the plant, read the k-step error "
    "(short horizons, from each logged pose, no policy in the loop): the profile with the lower score "
    "predicts the robots better, and at k = 1 the pose path (delay, noise, holds) dominates, at k = 30 "
    "the motors (lag, gains). To judge the outcome, read the envelope: a real outcome between the 5th "
    "and 95th percentile of the twins is what the profile expects; one outside it, in many runs, is a "
    "gap the profile does not cover."
)
"""The paragraph printed under the tables (and in docs/export.md's Replay section)."""


class ReplayError(ValueError):
    """A log and an export folder that do not belong together, or replay options that cannot be used
    (one line: what differs, or the option, what it takes and what it got)."""


def check_twin(log: RunLog, export: Path) -> dict:
    """The export folder's CONFIG once it is known to be the run's: the same policy weights, team,
    start poses and prey (ReplayError naming what differs)."""
    config = load_config(export)
    meta = log.meta
    weights = export / "weights.npy"
    sha = hashlib.sha256(weights.read_bytes()).hexdigest() if weights.is_file() else "heuristic"
    if meta.get("policy_sha256") not in (None, sha):
        raise ReplayError(
            f"--export {str(export)!r}: its policy (sha256 {sha[:12]}…) is not the one the run logged "
            f"({str(meta['policy_sha256'])[:12]}…)"
        )
    for key in ("task", "types", "capabilities", "ticks_per_step"):
        if meta.get(key) != config.get(key):
            raise ReplayError(
                f"--export {str(export)!r}: {key} {config.get(key)!r}, but the run logged {meta.get(key)!r}"
            )
    start = np.asarray(meta["start_poses"], dtype=float)
    if start.shape != np.shape(config["start_poses"]) or not np.allclose(start, config["start_poses"], atol=1e-9):
        raise ReplayError(f"--export {str(export)!r}: its start poses are not the run's")
    logged, want = layout_of(meta), layout_of(config)
    for key in sorted(set(logged) | set(want)):
        a, b = np.asarray(logged.get(key, []), dtype=float), np.asarray(want.get(key, []), dtype=float)
        if a.shape != b.shape or not np.allclose(a, b, atol=1e-9):
            raise ReplayError(f"--export {str(export)!r}: its task layout ({key}) is not the run's")
    return config


def check_options(reality: str, profiles: Sequence[str], k_steps: Sequence[int], draws: int, envelope: int) -> None:
    """The replay options, before anything runs (one-line errors naming the option): every profile
    a level or a readable profile file of :class:`~comat.reality.RealityConfig` fields, the horizons
    integers >= 1, ``draws`` >= 1, ``envelope`` 0 (none) or at least :data:`ENVELOPE_MIN_RUNS`."""
    resolve_reality(reality, "--reality")
    for p in profiles:
        resolve_reality(p, "--profiles")
    try:
        check_horizons(k_steps)
    except PlantError as err:
        raise ReplayError(str(err)) from None
    if isinstance(draws, bool) or not isinstance(draws, int) or draws < 1:
        raise ReplayError(f"--draws must be an integer >= 1, got {draws!r}")
    if (
        isinstance(envelope, bool)
        or not isinstance(envelope, int)
        or not (envelope == 0 or envelope >= ENVELOPE_MIN_RUNS)
    ):
        raise ReplayError(
            f"--envelope must be 0 (none) or an integer >= {ENVELOPE_MIN_RUNS} (twin runs), got {envelope!r}"
        )


def deployed_loop_of(meta: dict) -> str:
    """The loop the logged run ran, as comat runs it (:data:`comat.config.LOOPS`): its filter under its
    rps generation's constants, so the twin's commands are the run's for the same poses."""
    generation = "v2" if meta.get("rps") == "v2" else "legacy"
    return f"{'shipped' if meta.get('filter', 'comat') == 'comat' else 'robotarium'}_{generation}"


def step_poses(log: RunLog) -> np.ndarray:
    """(S, N, 3) the poses the real run's script received where each env step started."""
    return log.poses[(log.actions >= 0).all(axis=1)]


def twin_steps(log: RunLog) -> int | None:
    """The env steps the twin may take: the real run's, where it was stopped before its task ended
    without finishing (``COMAT_MAX_STEPS``: a twin left to run on would be judged on more steps);
    None (its own end) otherwise, also for a run cut short (it is compared as far as it logged)."""
    result = log.meta.get("result") or {}
    if not result or result.get("finished"):
        return None
    return int(result["steps"])


def _divergence(real: np.ndarray, twin: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per step and robot: position distance (m) and heading difference (rad), (S, N) each."""
    dist = np.hypot(*(real[..., :2] - twin[..., :2]).transpose(2, 0, 1))
    heading = np.abs(np.angle(np.exp(1j * (real[..., 2] - twin[..., 2]))))
    return dist, heading


def gap_rows(log: RunLog, twin: dict, dist: np.ndarray) -> list[dict]:
    """The gap table: the task metrics of the real run and its twin, and the position divergence."""
    real = log.meta.get("result") or {}
    rows = []
    for name in GAP_METRICS:
        r, t = real.get(name), float(twin["metrics"][name])
        rows.append({"quantity": name, "real": r, "twin": t, "gap": None if r is None else float(r) - t})
    per_step = dist.mean(axis=1)
    for label, value in (("mean", per_step.mean()), ("p95", np.percentile(per_step, 95)), ("max", dist.max())):
        rows.append({"quantity": f"position divergence {label} (m)", "real": None, "twin": None, "gap": float(value)})
    return rows


def _percentile(values: np.ndarray, x: float) -> float:
    """Where ``x`` falls among ``values`` (%): the share below it, ties counted half."""
    return float(100.0 * ((values < x).sum() + 0.5 * (values == x).sum()) / values.size)


def _baseline(twins: list[dict], steps: int, real_mean: float) -> dict:
    """Divergence of twins 1… from twin 0 over their common step starts (at most ``steps``): per twin
    its mean and maximum (m), and where the real run's mean divergence falls among those means."""
    means, maxima = [], []
    for other in twins[1:]:
        m = min(steps, len(twins[0]["measured"]), len(other["measured"]))
        dist = _divergence(twins[0]["measured"][:m], other["measured"][:m])[0]
        means.append(float(dist.mean()))
        maxima.append(float(dist.max()))
    means_a = np.array(means)
    return {
        "twins": len(means),
        "mean_m": float(means_a.mean()),
        "min_mean_m": float(means_a.min()),
        "max_mean_m": float(means_a.max()),
        "max_m": float(max(maxima)),
        "real_percentile": _percentile(means_a, real_mean) if len(means) >= ENVELOPE_MIN_RUNS - 1 else None,
    }


def _envelope_rows(log: RunLog, twins: list[dict]) -> list[dict]:
    """Per task metric: the real value, the twins' 5th, 50th and 95th percentiles, and the real
    value's percentile among the twins."""
    real = log.meta["result"]
    rows = []
    for name in GAP_METRICS:
        values = np.array([float(t["metrics"][name]) for t in twins])
        r = float(real[name])
        p5, p50, p95 = (float(v) for v in np.percentile(values, [5, 50, 95]))
        rows.append(
            {"quantity": name, "real": r, "p5": p5, "median": p50, "p95": p95, "percentile": _percentile(values, r)}
        )
    return rows


def _cell(v) -> str:
    return "" if v is None else f"{v:.4g}" if isinstance(v, float) else str(v)


def _label(profile: str) -> str:
    return Path(profile).name if profile.endswith((".yaml", ".yml")) else profile


def _kstep_section(scores: dict[str, dict], n: int, tier: str) -> tuple[str, list[dict]]:
    """The k-step table (Markdown, mm and mrad) with the ranking by score per horizon, and its CSV
    rows (m and rad, a row per profile, horizon and robot, then ``all``)."""
    first = next(iter(scores.values()))
    if not first["ks"]:
        short = f"The log is too short for any horizon (it needs {first['warmup']} + k + 1 iterations)."
        return f"\n### The plant: k-step prediction error\n\n{short}\n", []
    how = (
        f"From {first['starts']} logged poses (every {first['stride']} iterations; {first['skipped']} left out; "
        f"each rollout warmed up on the {first['warmup']} logged commands before it), the logged commands of the "
        f"next k ticks through each profile's plant ({tier} tier; {first['draws']} draws of its randomness, one at "
        "off), against the pose logged k ticks later. Position error per robot and over robots (mm), heading "
        "error (mrad), and the score (energy score of the positions, mm): lower is better.\n"
    )
    robots = " | ".join(f"robot {i}" for i in range(n))
    md = [
        "\n### The plant: k-step prediction error\n",
        how,
        f"| profile | k (ticks) | k (s) | {robots} | all | heading (mrad) | score |",
        "|---|---|---|" + "---|" * n + "---|---|---|",
    ]
    rows = []
    for profile, r in scores.items():
        for i, k in enumerate(r["ks"]):
            cells = " | ".join(f"{1000 * v:.2f}" for v in r["error_m"][i])
            md.append(
                f"| {profile} | {k} | {k * C.CONTROL_DT_S:.3g} | {cells} | {1000 * r['total_m'][i]:.2f} | "
                f"{1000 * r['heading_rad'][i]:.1f} | {1000 * r['score_m'][i]:.2f} |"
            )
            per_robot = [
                (str(j), r["error_m"][i, j], r["robot_heading_rad"][i, j], r["robot_score_m"][i, j]) for j in range(n)
            ]
            for robot, err, head, score in [*per_robot, ("all", r["total_m"][i], r["heading_rad"][i], r["score_m"][i])]:
                rows.append(
                    {
                        "profile": profile,
                        "k_ticks": k,
                        "k_s": round(k * C.CONTROL_DT_S, 6),
                        "robot": robot,
                        "position_error_m": float(err),
                        "heading_error_rad": float(head),
                        "score_m": float(score),
                    }
                )
    if len(scores) > 1:
        md.append("")
        for i, k in enumerate(first["ks"]):
            ranked = sorted(scores, key=lambda p: scores[p]["score_m"][i])
            md.append(f"- k = {k}: " + " < ".join(f"{p} {1000 * scores[p]['score_m'][i]:.2f}" for p in ranked))
    return "\n".join(md) + "\n", rows


def output_names(out: Path, envelope: int) -> list[str]:
    """The files ``replay`` writes beside the recording ``out`` (its own name first)."""
    stem = out.stem
    names = [out.name, f"{stem}_gap.md", f"{stem}_gap.csv", f"{stem}_kstep.csv"]
    return names + ([f"{stem}_envelope.csv"] if envelope else [])


def replay(
    log_path: str,
    export: str,
    out: str,
    tier: str = "unicycle",
    reality: str = "off",
    seed: int = 0,
    video: str | None = None,
    fps: int = 5,
    replay_commands: bool = False,
    profiles: Sequence[str] = (),
    k_steps: Sequence[int] = KSTEP_TICKS,
    draws: int = DRAWS,
    envelope: int = 0,
) -> dict:
    # long: the replay report: twin, envelope, k-step scores, files, in the report's order
    """Lay the run logged at ``log_path`` beside its twin from the export folder ``export`` and score
    the plant of ``reality`` and of each of ``profiles`` on it (module docstring); writes ``out``
    (``.rrd``) and the tables beside it (:func:`output_names`), with ``video`` (``.mp4``/``.gif``)
    both runs drawn top-down, a frame per env step at ``fps``. ``replay_commands``: also the logged
    commands played open-loop through the plant. ``k_steps``, ``draws``: the k-step horizons (ticks)
    and draws per start; ``envelope``: twin runs for the envelope (0: none).

    Returns ``{"rows": gap rows, "steps": compared steps, "complete": the run finished, "kstep":
    {profile: :func:`~comat.eval.plant.kstep_errors`}, "baseline": sim-to-sim baseline, "envelope":
    rows or None, "files": [...], "markdown": the tables}``.

    Raises:
        comat.runlog.RunLogError: the log cannot be read; ReplayError: the folder is not the run's,
        or an option that cannot be used.
    """
    check_options(reality, profiles, k_steps, draws, envelope)
    log = read_run_log(log_path)
    export_dir = Path(export)
    config = check_twin(log, export_dir)
    loop = deployed_loop_of(log.meta)
    layer = None if reality == "off" else reality
    start, cap = np.asarray(log.poses[0], dtype=float), twin_steps(log)
    twin = mujoco_twin(export_dir, tier=tier, reality=layer, seed=seed, loop=loop, start_poses=start, max_steps=cap)
    real = step_poses(log)
    steps = min(len(real), len(twin["poses"]))
    if steps == 0:
        raise ReplayError(f"{log_path}: the log holds no env step start to compare (a run stopped at once)")
    real, twin_poses = real[:steps], twin["measured"][:steps]
    dist, heading = _divergence(real, twin_poses)
    rows = gap_rows(log, twin, dist)
    played = None
    if replay_commands:
        runs = open_loop(log, reality, tier, draws, seed)[:, (log.actions >= 0).all(axis=1)][:, :steps]
        played = runs[0]
        open_dist = np.stack([_divergence(real, p)[0] for p in runs])  # (D, S, N)
        rows += [
            {"quantity": f"open-loop divergence {label} (m)", "real": None, "twin": None, "gap": float(value)}
            for label, value in (("mean", open_dist.mean()), ("max", open_dist.max(axis=(1, 2)).mean()))
        ]

    # the sim-to-sim baseline and the envelope: more twins, differing only in the layer's seed
    runs = envelope if envelope and log.complete else 2  # a run cut short has no outcome to place
    if layer is None:  # at off the layer's seed changes nothing: every twin is this one
        twins = [twin] * runs
    else:
        twins = [twin] + [
            mujoco_twin(
                export_dir, tier=tier, reality=layer, seed=seed + j, loop=loop, start_poses=start, max_steps=cap
            )
            for j in range(1, runs)
        ]
    real_mean = float(dist.mean())
    baseline = None if layer is None else _baseline(twins, steps, real_mean)
    envelope_rows = _envelope_rows(log, twins) if envelope and log.complete else None

    scores = {p: kstep_errors(log, p, k_steps, tier, draws, seed) for p in dict.fromkeys([reality, *profiles])}
    kstep_md, kstep_rows = _kstep_section(scores, log.n, tier)

    note = (
        f"Real run: {log.meta.get('task')} with {log.n} robots under rps {log.meta.get('rps')} "
        f"({'ran to its end' if log.complete else 'cut short: no result, compared as far as it logged'}), "
        f"{len(log.t)} iterations. Twin: the same team, policy and task in MuJoCo ({tier} tier, reality "
        f"{reality}, the run's loop {loop}), from the run's logged first poses"
        f"{'' if cap is None else f', for its {cap} env steps'}. Divergence: the poses the real script received "
        f"against those the twin's script saw, at the start of each of {steps} env steps."
    )
    if baseline is None:
        line = "Sim-to-sim baseline: 0 m (at off the twin is deterministic: every run of it is the same)."
    else:
        line = (
            f"Sim-to-sim baseline: twins that differ only in the layer's seed ({seed} against "
            f"{seed + 1}…{seed + baseline['twins']}) diverge by {baseline['mean_m']:.4g} m on average "
            f"(per twin {baseline['min_mean_m']:.4g}–{baseline['max_mean_m']:.4g} m, "
            f"at most {baseline['max_m']:.4g} m); "
            f"the real run by {real_mean:.4g} m"
            + (
                ""
                if baseline["real_percentile"] is None
                else f", at the {baseline['real_percentile']:.0f}th percentile of the twins'"
            )
            + "."
        )
    md = ["| quantity | real | twin | real − twin |", "|---|---|---|---|"]
    md += [f"| {r['quantity']} | {_cell(r['real'])} | {_cell(r['twin'])} | {_cell(r['gap'])} |" for r in rows]
    text = "\n".join(md) + f"\n\n{note}\n\n{line}\n" + kstep_md
    if envelope:
        if envelope_rows is None:
            text += (
                f"\n### Envelope\n\nNo envelope: the run did not finish, so it has no outcome to place among "
                f"{envelope} twins.\n"
            )
        else:
            text += (
                f"\n### Envelope: the real outcome among {envelope} twins (seeds {seed}…{seed + envelope - 1})\n\n"
                + ("At off every twin is the same run (the layer's seed changes nothing).\n\n" if layer is None else "")
                + "| quantity | real | twins p5 | median | p95 | real's percentile |\n|---|---|---|---|---|---|\n"
            )
            text += "\n".join(
                "| "
                + " | ".join(_cell(r[key]) for key in ("quantity", "real", "p5", "median", "p95"))
                + f" | {r['percentile']:.0f} |"
                for r in envelope_rows
            )
            text += "\n"
    text += f"\n{READING}\n"

    out_path = Path(out)
    names = output_names(out_path, envelope)
    files = [out_path.with_name(name) for name in names]
    record(files[0], real, twin_poses, dist, heading, text, list(config["types"]), played)
    write_atomic(files[1], text)
    write_atomic(files[2], csv_text(rows, ["quantity", "real", "twin", "gap"]))
    kstep_fields = ["profile", "k_ticks", "k_s", "robot", "position_error_m", "heading_error_rad", "score_m"]
    write_atomic(files[3], csv_text(kstep_rows, kstep_fields))
    if envelope:
        fields = ["quantity", "real", "p5", "median", "p95", "percentile"]
        write_atomic(files[4], csv_text(envelope_rows or [], fields))
    if video is not None:
        title = f"real (filled) · twin at {_label(reality)} (purple)"
        files.append(draw_video(Path(video), log, config, real, twin_poses, dist, fps, title))
    return {
        "rows": rows,
        "steps": steps,
        "complete": log.complete,
        "kstep": scores,
        "baseline": baseline,
        "envelope": envelope_rows,
        "files": files,
        "markdown": text,
    }
