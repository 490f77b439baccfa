"""What a hardware campaign brings back, read: ``comat campaign --analyze RETURNED --manifest M --out OUT``.

The Robotarium returns, per experiment, the script's stdout as ``log.txt``, the data files the run
wrote (``comat_run.npy`` and ``comat_run.meta.npy``, :mod:`comat.runlog`), the scripts and a video.
``RETURNED`` holds one subfolder per folder of the campaign's manifest
(:mod:`comat.eval.campaign`), named as that folder, with what its experiment returned.

=====================  ========================================================================
Checked first          (:func:`check_returned`; a one-line CampaignError, nothing written):
                       ``RETURNED`` is a folder; it holds a subfolder for every manifest folder
                       (an experiment that never ran gets an empty one) and nothing else; a
                       subfolder holds only what an experiment returns (``log.txt``, the two
                       log files, the folder's own scripts, a video or image): anything else
                       is a foreign file; a readable log is the run of its manifest folder
                       (the same policy sha256, seed, team, start poses and layout)
Per run                its failures (:func:`run_failures`): missing files, an unreadable log,
                       a crash (a traceback in ``log.txt`` and no result), a timeout (a log
                       without result: interrupted), a run within 10 % of its declared time,
                       collisions (the Robotarium's test on the logged poses: centres offset
                       0.025 m forward <= 0.135 m apart; and rps's own count), boundary
                       errors, freezes (:func:`log_freezes`: a robot sent 0.15 m of motion
                       or 2 rad of turn in 3 s that stayed within 2 cm (and 0.1 rad); a team
                       whose robots that wanted to move all moved < 2 cm in 3 s);
                       its replay beside its twin (:func:`comat.eval.replay.replay`, layer seed
                       = the run's index): ``OUT/runs/<folder>/replay.rrd`` and its tables
Per team size          the paired sim/real table: for progress, return, steps and finished the
                       mean over the runs that finished their log (a result), real and twin,
                       and their paired difference, each with a 95 % t-interval over runs
                       (runs are the replicated unit: robots in one run are not independent);
                       the divergence; runs with each failure
Written (OUT)          ``campaign.md`` (tables, failure list, per-run table), ``sizes.csv``,
                       ``runs.csv``, ``failures.csv``, ``runs/<folder>/`` (the replay's files);
                       into ``.OUT.tmp-*`` beside OUT, renamed at the end; an existing OUT is
                       an error
=====================  ========================================================================
"""

from __future__ import annotations

import json
import shutil
import tempfile
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from comat import constants as C
from comat.eval.campaign import RETURNED_LOG, CampaignError, read_manifest
from comat.eval.replay import ReplayError, check_options, check_twin, replay
from comat.files import csv_text, write_atomic
from comat.measure.stats import t_interval
from comat.runlog import LOG_FILE, META_FILE, RunLog, RunLogError, read_run_log
from sim2real.check import duration_warning

__all__ = [
    "FREEZE_INTENT_M",
    "FREEZE_INTENT_RAD",
    "FREEZE_MOVE_M",
    "FREEZE_TURN_RAD",
    "FREEZE_WINDOW_S",
    "QUANTITIES",
    "RETURNED_MEDIA",
    "analyze_campaign",
    "check_returned",
    "log_collisions",
    "log_freezes",
    "run_failures",
]

RETURNED_MEDIA = (".mp4", ".avi", ".mov", ".mkv", ".webm", ".gif", ".png", ".jpg", ".jpeg")
"""Files a returned experiment may hold besides its log and scripts: the video the Robotarium
records, a saved figure."""
RETURNED_DATA = (RETURNED_LOG, LOG_FILE, META_FILE)
"""What every returned experiment should hold (a missing one is a failure of that run)."""
LEFTOVER = f"{META_FILE}.tmp.npy"
"""The metadata's temporary file (:class:`comat.runlog.RunLogWriter`), left by a run stopped mid-save."""
QUANTITIES = ("progress", "return", "steps", "finished")
"""Task metrics of the paired table (the log's result against the twin's)."""
FREEZE_WINDOW_S = 3.0
"""Freezes are judged over every window this long (the safety battery's team freeze: 91 ticks)."""
FREEZE_MOVE_M = 0.02
"""A robot whose logged position moved less than this over a window stood still (as the battery)."""
FREEZE_INTENT_M = 0.15
"""Commands worth this much motion over a window (0.05 m/s on average, above ``nominal``'s dead
zone of 0.03 m/s) mean the robot was meant to move: measured on 10 stand-in runs under ``nominal``
(PCP, 2-8 robots), commands sent over 3 s outran the logged motion by at most 0.11 m, at a reversal."""
FREEZE_INTENT_RAD = 2.0
"""Turn commands worth this much heading over a window (0.67 rad/s on average) mean the robot was
meant to turn: in 28 clean stand-in runs, where the logged heading spanned < FREEZE_TURN_RAD over a
window, the commands sent asked for at most 1.01 rad; a robot whose wheels stopped (a fault at
speed fraction 0) kept being sent 3.3-8.2 rad."""
FREEZE_TURN_RAD = 0.1
"""A robot whose logged heading spanned less than this over a window did not turn."""
COLLISION_DISTANCE_M = 0.135
"""The Robotarium's collision test: offset centres (COLLISION_OFFSET_M ahead) this close or closer
(the exported main.py's ``offset_collisions``, the 2025 rule)."""
_CHUNK_ROWS = 2048
"""Log rows whose (rows, N, N) robot distances are held at once."""


def check_returned(returned: Path, manifest: dict, manifest_dir: Path) -> list[dict]:
    """The returned folder against the manifest, before anything runs (module docstring: Checked
    first). Returns per manifest folder ``{"entry", "path", "export", "log" (RunLog or None),
    "log_error" (str or None), "stdout" (str or None), "missing" [file names]}``."""
    if not returned.is_dir():
        why = "a file" if returned.exists() else "no such folder"
        raise CampaignError(
            f"--analyze must be the folder holding each experiment's download, got {str(returned)!r} ({why})"
        )
    names = [e["folder"] for e in manifest["folders"]]
    present = sorted(p.name for p in returned.iterdir() if not p.name.startswith("."))
    foreign = [n for n in present if n not in names or not (returned / n).is_dir()]
    if foreign:
        raise CampaignError(
            f"--analyze {str(returned)!r}: expected only the manifest's folders ({names[0]} …), got foreign {foreign}"
        )
    absent = [n for n in names if n not in present]
    if absent:
        raise CampaignError(
            f"--analyze {str(returned)!r}: expected a folder per manifest folder (an empty one for an experiment "
            f"that never ran), got none for {absent}"
        )
    runs = []
    for entry in manifest["folders"]:
        path, export = returned / entry["folder"], manifest_dir / entry["folder"]
        allowed = {*RETURNED_DATA, LEFTOVER, *(p.name for p in export.iterdir())}
        files = sorted(p.name for p in path.iterdir() if not p.name.startswith("."))
        odd = [f for f in files if f not in allowed and not f.lower().endswith(RETURNED_MEDIA)]
        if odd:
            raise CampaignError(
                f"--analyze {str(path)!r}: expected what an experiment returns ({', '.join(RETURNED_DATA)}, its "
                f"scripts, a video), got foreign {odd}"
            )
        run = {"entry": entry, "path": path, "export": export, "log": None, "log_error": None, "stdout": None}
        run["missing"] = [f for f in RETURNED_DATA if f not in files]
        if RETURNED_LOG in files:
            run["stdout"] = (path / RETURNED_LOG).read_text(errors="replace")
        if LOG_FILE in files and META_FILE in files:
            try:
                run["log"] = read_run_log(str(path))
            except RunLogError as err:
                run["log_error"] = str(err)
        if run["log"] is not None:
            _check_log_is_entry(run["log"], entry, export, path)
        runs.append(run)
    return runs


def _check_log_is_entry(log: RunLog, entry: dict, export: Path, path: Path) -> None:
    """A readable log must be its manifest folder's run (CampaignError: the manifest does not match)."""
    if log.meta.get("seed") != entry["seed"]:
        raise CampaignError(
            f"--manifest does not match {str(path)!r}: its folder {entry['folder']} has seed {entry['seed']}, "
            f"the log there seed {log.meta.get('seed')!r}"
        )
    try:
        check_twin(log, export)
    except (ReplayError, ValueError) as err:
        raise CampaignError(f"--manifest does not match {str(path)!r}: {err}") from None


def _result_line(stdout: str | None) -> dict | None:
    """The last ``COMAT_RESULT {json}`` line of a run's stdout (None: there is none)."""
    lines = [ln for ln in (stdout or "").splitlines() if ln.startswith("COMAT_RESULT ")]
    if not lines:
        return None
    try:
        return json.loads(lines[-1][len("COMAT_RESULT ") :])
    except json.JSONDecodeError:
        return None


def log_collisions(poses: np.ndarray) -> dict:
    """The Robotarium's collision test on logged poses (K, N, 3): ``{"pair_iterations", "first"
    (iteration, robot i, robot j) or None, "closest_m"}`` (offset centres; robots vectorized, rows
    in chunks)."""
    k, n = poses.shape[:2]
    out = {"pair_iterations": 0, "first": None, "closest_m": None}
    if n < 2 or k == 0:
        return out
    upper = np.triu(np.ones((n, n), dtype=bool), 1)
    closest = np.inf
    for start in range(0, k, _CHUNK_ROWS):  # a loop over row chunks, not over robot pairs
        p = poses[start : start + _CHUNK_ROWS].astype(float)
        c = p[..., :2] + C.COLLISION_OFFSET_M * np.stack([np.cos(p[..., 2]), np.sin(p[..., 2])], axis=-1)
        d = np.linalg.norm(c[:, :, None] - c[:, None], axis=-1)[:, upper]  # (rows, pairs)
        closest = min(closest, float(d.min()))
        hit = d <= COLLISION_DISTANCE_M  # as main.py counts them (offset_collisions)
        out["pair_iterations"] += int(hit.sum())
        if out["first"] is None and hit.any():
            row, pair = np.argwhere(hit)[0]
            i, j = np.argwhere(upper)[pair]
            out["first"] = (int(start + row), int(i), int(j))
    out["closest_m"] = closest
    return out


def _window_sums(x: np.ndarray, w: int) -> np.ndarray:
    """Sums of ``w`` consecutive rows of ``x`` (K, ...): (K - w + 1, ...), row k summing rows k … k + w - 1."""
    c = np.concatenate([np.zeros((1, *x.shape[1:])), np.cumsum(x, axis=0)])
    return c[w:] - c[:-w]


def _covered(windows: np.ndarray, w: int, rows: int) -> np.ndarray:
    """(rows, ...) True where a row lies inside a window (K - w + 1, ...) that is True."""
    edges = np.zeros((rows + 1, *windows.shape[1:]), dtype=np.int64)
    edges[: len(windows)] += windows
    edges[w : w + len(windows)] -= windows
    return np.cumsum(edges, axis=0)[:-1] > 0


def log_freezes(log: RunLog) -> dict:
    """Freezes in a run's log, over every window of FREEZE_WINDOW_S (module docstring):

    * ``"robots"``: per robot sent commands that would move it at least FREEZE_INTENT_M (the sent
      speeds integrated along its logged heading) over a window in which its logged position stayed
      inside a box of diagonal FREEZE_MOVE_M (not a robot reversing in place, whose net motion is
      small too), or sent turns worth FREEZE_INTENT_RAD over a window in which it also did not turn
      (heading span < FREEZE_TURN_RAD): stuck, or not tracked; ``{"robot", "first_iteration",
      "seconds"}``;
    * ``"team"``: windows in which at least one robot wanted to move (its commands before the
      filter worth FREEZE_INTENT_M) and every such robot moved less than FREEZE_MOVE_M (the filter
      held them: a deadlock, the bench's team freeze); ``{"first_iteration", "robots", "seconds"}``
      or None.
    """
    w = round(FREEZE_WINDOW_S / C.CONTROL_DT_S)
    rows = len(log.t)
    if rows < w:
        return {"robots": [], "team": None}
    heading = log.poses[..., 2].astype(float)
    ahead = np.stack([np.cos(heading), np.sin(heading)], axis=-1) * C.CONTROL_DT_S  # (K, N, 2)
    sent = np.linalg.norm(_window_sums(log.sent[..., :1] * ahead, w), axis=-1)  # (K - w + 1, N) m
    wanted = np.linalg.norm(_window_sums(log.nominal[..., :1] * ahead, w), axis=-1)
    xy = log.poses[..., :2].astype(float)
    still = np.linalg.norm(xy[w - 1 :] - xy[: rows - w + 1], axis=-1) < FREEZE_MOVE_M  # net motion
    view = np.lib.stride_tricks.sliding_window_view(xy, w, axis=0)  # (K - w + 1, N, 2, w), no copy
    boxed = np.linalg.norm(view.max(axis=-1) - view.min(axis=-1), axis=-1) < FREEZE_MOVE_M
    heading_view = np.lib.stride_tricks.sliding_window_view(np.unwrap(heading, axis=0), w, axis=0)
    turned = heading_view.max(axis=-1) - heading_view.min(axis=-1) >= FREEZE_TURN_RAD  # (K - w + 1, N)
    turns = np.abs(_window_sums(log.sent[..., 1] * C.CONTROL_DT_S, w))  # rad asked for
    stuck = boxed & ((sent >= FREEZE_INTENT_M) | ((turns >= FREEZE_INTENT_RAD) & ~turned))
    robot_s = _covered(stuck, w, rows).sum(axis=0) * C.CONTROL_DT_S
    robots = [
        {"robot": int(i), "first_iteration": int(np.flatnonzero(stuck[:, i])[0]), "seconds": float(robot_s[i])}
        for i in np.flatnonzero(stuck.any(axis=0))
    ]
    movers = wanted >= FREEZE_INTENT_M
    team = movers.any(axis=1) & (still | ~movers).all(axis=1)  # (K - w + 1,)
    if not team.any():
        return {"robots": robots, "team": None}
    k = int(np.flatnonzero(team)[0])
    seconds = float(_covered(team, w, rows).sum() * C.CONTROL_DT_S)
    return {
        "robots": robots,
        "team": {"first_iteration": k, "robots": np.flatnonzero(movers[k]).tolist(), "seconds": seconds},
    }


def run_failures(run: dict) -> list[dict]:
    """What went wrong in one returned run: ``[{"kind", "detail"}]`` (module docstring: Per run)."""
    entry, log, stdout = run["entry"], run["log"], run["stdout"]
    fails = []
    if run["missing"]:
        fails.append({"kind": "missing files", "detail": f"not returned: {', '.join(run['missing'])}"})
    if run["log_error"]:
        fails.append({"kind": "unreadable log", "detail": run["log_error"]})
    result = (log.meta.get("result") if log is not None else None) or _result_line(stdout)
    if stdout is not None and result is None:
        trace = [ln.strip() for ln in stdout.splitlines() if ln.strip()]
        if any(ln.startswith("Traceback") for ln in trace):
            fails.append({"kind": "crash", "detail": f"log.txt ends: {trace[-1][:200]}"})
    if log is not None and not log.complete:
        fails.append(
            {
                "kind": "timeout",
                "detail": f"the log stops at iteration {len(log.t)} ({float(log.t[-1]):.0f} s of loop, step "
                f"{int(log.step[-1])}) with no result: interrupted (declared {entry['duration_s']} s) or crashed",
            }
        )
    if result is not None:
        warning = duration_warning({"duration_s": entry["duration_s"], **_startup(entry)}, result)
        if warning:
            fails.append({"kind": "near timeout", "detail": warning})
        boundary = int((result.get("rps_errors") or {}).get("boundary", 0) or 0)
        if boundary:
            fails.append({"kind": "boundary", "detail": f"rps reported {boundary} boundary errors"})
    rps_collisions = int(((result or {}).get("rps_errors") or {}).get("collision", 0) or 0)
    hits = log_collisions(log.poses) if log is not None else {"pair_iterations": 0, "first": None}
    if hits["pair_iterations"] or rps_collisions:
        where = ""
        if hits["first"] is not None:
            it, i, j = hits["first"]
            where = f"; first robots {i} and {j} at iteration {it} ({float(log.t[it]):.1f} s), closest "
            where += f"{hits['closest_m']:.3f} m"
        fails.append(
            {
                "kind": "collision",
                "detail": f"{hits['pair_iterations']} pair-iterations in the logged poses (offset centres <= "
                f"{COLLISION_DISTANCE_M} m){where}; rps reported {rps_collisions}",
            }
        )
    frozen = log_freezes(log) if log is not None else {"robots": [], "team": None}
    for f in frozen["robots"]:
        fails.append(
            {
                "kind": "freeze (robot)",
                "detail": f"robot {f['robot']} was sent >= {FREEZE_INTENT_M} m or {FREEZE_INTENT_RAD:g} rad of "
                f"motion per {FREEZE_WINDOW_S:g} s but stayed within {FREEZE_MOVE_M} m, from iteration "
                f"{f['first_iteration']} ({f['seconds']:.1f} s in all): stuck, or not tracked",
            }
        )
    if frozen["team"] is not None:
        f = frozen["team"]
        fails.append(
            {
                "kind": "freeze (team)",
                "detail": f"every robot that wanted to move ({f['robots']}) moved < {FREEZE_MOVE_M} m per "
                f"{FREEZE_WINDOW_S:g} s from iteration {f['first_iteration']} ({f['seconds']:.1f} s in all): held "
                "still (a deadlock)",
            }
        )
    return fails


def _startup(entry: dict) -> dict:
    return {"startup_drive_s": entry.get("startup_drive_s", 0.0)}


def _interval(values: list[float]) -> dict:
    if not values:
        return {"mean": None, "lo": None, "hi": None, "n": 0}
    ci = t_interval(values)
    return {k: (None if not np.isfinite(ci[k]) else float(ci[k])) for k in ("mean", "lo", "hi")} | {"n": len(values)}


def _fmt(ci: dict, digits: int = 3) -> str:
    if ci["mean"] is None:
        return "–"
    if ci["lo"] is None:
        return f"{ci['mean']:.{digits}g} (one run)"
    return f"{ci['mean']:.{digits}g} [{ci['lo']:.{digits}g}, {ci['hi']:.{digits}g}]"


def size_rows(runs: list[dict], profiles: Sequence[str] = (), k_steps: Sequence[int] = ()) -> list[dict]:
    """The paired table: per team size and quantity, real, twin and real − twin over the runs with a
    result (t-intervals over runs), the divergence (over every replayed run), and per profile and
    horizon the plant's k-step score on the runs' logs (mm, over the runs long enough for it)."""
    rows = []
    for size in sorted({r["entry"]["size"] for r in runs}):
        mine = [r for r in runs if r["entry"]["size"] == size]
        paired = [r for r in mine if r.get("real") is not None]
        for q in QUANTITIES:
            real = [float(r["real"][q]) for r in paired]
            twin = [float(r["twin"][q]) for r in paired]
            rows.append(
                {
                    "size": size,
                    "quantity": q,
                    "runs": len(mine),
                    "real": _interval(real),
                    "twin": _interval(twin),
                    "gap": _interval([a - b for a, b in zip(real, twin)]),
                }
            )
        div = [r["divergence_m"] for r in mine if r.get("divergence_m") is not None]
        none = {"mean": None, "lo": None, "hi": None, "n": 0}
        rows.append(
            {
                "size": size,
                "quantity": "divergence mean (m)",
                "runs": len(mine),
                "real": none,
                "twin": none,
                "gap": _interval(div),
            }
        )
        for p in profiles:
            for k in k_steps:
                score = [1000 * r["kstep"][p][k] for r in mine if k in (r.get("kstep") or {}).get(p, {})]
                name = f"plant score {_label(p)} k = {k} (mm)"
                rows.append({"size": size, "quantity": name, "runs": len(mine), "real": none, "twin": none})
                rows[-1]["gap"] = _interval(score)
    return rows


def analyze_campaign(
    returned: str | Path,
    manifest_path: str | Path,
    out: str | Path,
    reality: str = "off",
    tier: str = "unicycle",
    k_steps: tuple[int, ...] = (1, 5, 30),
    draws: int = 8,
    progress: Callable[[str], None] | None = None,
    profiles: Sequence[str] = (),
) -> dict:
    """Read a campaign's returned folder against its manifest and write the analysis in ``out``
    (module docstring). ``reality``, ``tier``, ``k_steps``, ``draws``: each run's twin and plant
    score (:func:`comat.eval.replay.replay`), ``profiles``: more levels or profiles whose plants are
    scored on every run's log (the table ranks them per size); ``progress``: told a line per run once every check has
    passed (the command prints it). Returns ``{"sizes": rows, "runs": [...], "failures":
    [...], "markdown": campaign.md's text, "out": Path}``."""
    returned, manifest_path, out = Path(returned), Path(manifest_path), Path(out)
    check_options(reality, profiles, k_steps, draws, 0)
    manifest = read_manifest(manifest_path)
    if out.exists():
        raise CampaignError(f"--out {str(out)!r} already exists; choose a new folder")
    runs = check_returned(returned, manifest, manifest_path.parent)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.tmp-", dir=out.parent))
    try:
        failures = []
        for k, run in enumerate(runs, 1):
            entry = run["entry"]
            if progress is not None:
                what = "beside its twin" if run["log"] is not None else "no log to replay"
                progress(f"[{k}/{len(runs)}] {entry['folder']}: {what}")
            for f in run_failures(run):
                failures.append({"folder": entry["folder"], "size": entry["size"], "run": entry["run"], **f})
            run["real"] = run["twin"] = run["divergence_m"] = None
            if run["log"] is None:
                continue
            folder = tmp / "runs" / entry["folder"]
            folder.mkdir(parents=True)
            rep = replay(
                str(run["path"]),
                str(run["export"]),
                str(folder / "replay.rrd"),
                tier=tier,
                reality=reality,
                seed=entry["run"],
                k_steps=k_steps,
                draws=draws,
                profiles=profiles,
            )
            run["kstep"] = {p: dict(zip(sc["ks"], sc["score_m"])) for p, sc in rep["kstep"].items()}
            by_name = {r["quantity"]: r for r in rep["rows"]}
            run["divergence_m"] = by_name["position divergence mean (m)"]["gap"]
            if run["log"].complete:
                run["real"] = {q: by_name[q]["real"] for q in QUANTITIES}
                run["twin"] = {q: by_name[q]["twin"] for q in QUANTITIES}
        rows = size_rows(runs, list(dict.fromkeys([reality, *profiles])), k_steps)
        text = _markdown(manifest, rows, runs, failures, reality, tier)
        write_atomic(tmp / "campaign.md", text)
        write_atomic(tmp / "sizes.csv", csv_text([_flat(r) for r in rows], list(_flat(rows[0]))))
        run_rows = [_run_row(r, failures) for r in runs]
        write_atomic(tmp / "runs.csv", csv_text(run_rows, list(run_rows[0])))
        write_atomic(tmp / "failures.csv", csv_text(failures, ["folder", "size", "run", "kind", "detail"]))
        tmp.chmod(0o755)
        tmp.rename(out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return {"sizes": rows, "runs": runs, "failures": failures, "markdown": text, "out": out}


def _label(profile: str) -> str:
    return Path(profile).name if profile.endswith((".yaml", ".yml")) else profile


def _flat(row: dict) -> dict:
    flat = {"size": row["size"], "quantity": row["quantity"], "runs": row["runs"], "paired": row["gap"]["n"]}
    for side in ("real", "twin", "gap"):
        flat |= {f"{side}_{k}": row[side][k] for k in ("mean", "lo", "hi")}
    return flat


def _run_row(run: dict, failures: list[dict]) -> dict:
    e = run["entry"]
    row = {"folder": e["folder"], "size": e["size"], "run": e["run"], "team": e["team"], "seed": e["seed"]}
    row["log"] = "none" if run["log"] is None else "complete" if run["log"].complete else "cut short"
    for side in ("real", "twin"):
        row |= {f"{side}_{q}": (run[side] or {}).get(q) for q in QUANTITIES}
    row["divergence_m"] = run["divergence_m"]
    row["failures"] = "; ".join(f["kind"] for f in failures if f["folder"] == e["folder"])
    return row


def _markdown(manifest: dict, rows: list[dict], runs: list[dict], failures: list[dict], reality: str, tier: str) -> str:
    md = [
        f"# Campaign analysis: {manifest['policy']} on {manifest['task']}",
        "",
        (
            f"{len(runs)} experiments (sizes {manifest['sizes']} × {manifest['runs']} runs), policy sha256 "
            f"`{manifest['policy_sha256'][:12]}`, comat {manifest['comat_version']} at `{manifest['comat_commit']}`. "
            f"Each run's twin: the same team, policy and task in MuJoCo ({tier} tier, reality {reality}, layer "
            "seed = the run's index), from the poses the run logged first (`comat replay`)."
        ),
        "",
        "## Paired sim/real table per team size",
        "",
        (
            "Means over the runs whose log holds a result, with 95 % t-intervals over runs (runs are the "
            "replicated unit; one run gives no interval). real − twin is the paired difference, run by run. The "
            "divergence is the mean distance between the real and the twin's poses at each env step's start, over "
            "every replayed run. A plant score is the k-step score of a profile's plant on the runs' logs (`comat "
            "replay`: from each logged pose, the logged commands k ticks ahead; lower predicts the robots better), "
            "over the runs long enough for k."
        ),
        "",
        "| robots | quantity | runs (paired) | real | twin | real − twin |",
        "|---|---|---|---|---|---|",
    ]
    md += [
        f"| {r['size']} | {r['quantity']} | {r['runs']} ({r['gap']['n']}) | {_fmt(r['real'])} | {_fmt(r['twin'])} | "
        f"{_fmt(r['gap'])} |"
        for r in rows
    ]
    md += ["", "## Failures", ""]
    if failures:
        md += ["| folder | robots | run | kind | detail |", "|---|---|---|---|---|"]
        md += [f"| {f['folder']} | {f['size']} | {f['run']} | {f['kind']} | {f['detail']} |" for f in failures]
        kinds = sorted({f["kind"] for f in failures})
        md += ["", "Runs with each kind, per team size:", ""]
        md += ["| robots | " + " | ".join(kinds) + " |", "|---|" + "---|" * len(kinds)]
        for size in manifest["sizes"]:
            counts = [len({f["folder"] for f in failures if f["size"] == size and f["kind"] == k}) for k in kinds]
            md.append(f"| {size} | " + " | ".join(str(c) for c in counts) + " |")
    else:
        md.append(
            "None: every experiment returned its files, finished its log, and no robot collided, left the "
            "arena or froze."
        )
    md += [
        "",
        "## Runs",
        "",
        "| folder | team | log | progress real / twin | divergence (m) | replay |",
        "|---|---|---|---|---|---|",
    ]
    for r in runs:
        e = r["entry"]
        log = "none" if r["log"] is None else "complete" if r["log"].complete else "cut short"
        prog = "–" if r["real"] is None else f"{r['real']['progress']:.3g} / {r['twin']['progress']:.3g}"
        div = "–" if r["divergence_m"] is None else f"{r['divergence_m']:.3g}"
        rrd = "–" if r["log"] is None else f"runs/{e['folder']}/replay.rrd"
        md.append(f"| {e['folder']} | {e['team']} | {log} | {prog} | {div} | {rrd} |")
    return "\n".join(md) + "\n"
