"""A hardware campaign: one policy on the Robotarium across team sizes × runs (``comat campaign``).

=====================  ========================================================================
What it writes         ``OUT/<task>_n<size>_r<run>/``: one submission folder per (team size, run),
                       each :func:`sim2real.export.export_submission` of the same policy;
                       ``OUT/manifest.json`` (:data:`MANIFEST_FORMAT`, read back by
                       :func:`read_manifest`) and ``OUT/manifest.md`` (the same for a person:
                       what to declare per folder and how to bring the runs back)
Teams                  for each size, the teams of that size in the sets ``sets`` (default
                       U_test then U_scale, :data:`DEFAULT_SETS`), in an order drawn from
                       ``[seed, size]``; run r takes the r-th (cycling when a size has fewer
                       teams than runs): runs at one size differ in team where the sets allow.
                       A size no set has is an error naming the sizes there are
Seeds                  folder (size, run) is exported with seed ``seed + 100 · run + size``
                       (start poses and task layout), so every folder starts differently
Manifest entry         folder, size, run, team (``set:K``), types, capabilities, seed, robots,
                       ``duration_s`` / ``horizon_s`` / ``startup_drive_s`` (what the export
                       declares), the policy's sha256; at the top the task, the policy, its
                       sha256, comat's version and commit, seed, sizes, runs, sets, filter
Determinism            the same arguments write the same folders and manifest (no time stamps)
Atomicity              everything goes into ``.OUT.tmp-*`` beside ``OUT``, renamed at the end;
                       on an error nothing is left; an existing ``OUT`` is an error
=====================  ========================================================================

What comes back and how it is read: :mod:`comat.eval.campaign_returns` (``comat campaign
--analyze``). :func:`stand_in_returns` makes such a returned folder without the Robotarium: each
folder's ``main.py`` run under ``rps`` (optionally inside a reality layer), its log and stdout put
where the Robotarium puts them, a dress rehearsal of the analysis and its test.
"""

from __future__ import annotations

import json
import shutil
import tempfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from comat.envs.base import resolve_coalitions
from comat.files import write_atomic
from comat.rl import source_commit
from comat.runlog import LOG_FILE, META_FILE
from comat.team import COALITION_SETS, SET_LABELS
from sim2real.check import CheckError, run_rps
from sim2real.export import export_submission, load_config

__all__ = [
    "DEFAULT_SETS",
    "MANIFEST_FILE",
    "MANIFEST_FORMAT",
    "MANIFEST_VERSION",
    "RETURNED_LOG",
    "CampaignError",
    "folder_name",
    "make_campaign",
    "parse_sets",
    "parse_sizes",
    "plan_teams",
    "read_manifest",
    "stand_in_returns",
]

MANIFEST_FORMAT = "comat-campaign"
MANIFEST_VERSION = 1
"""Bumped whenever the manifest's fields change meaning; :func:`read_manifest` refuses another."""
MANIFEST_FILE = "manifest.json"
MANIFEST_MD = "manifest.md"
DEFAULT_SETS = ("test", "scale")
"""Where a campaign's teams come from: the unseen compositions (U_test, sizes 2-8) and the large
ones (U_scale, 10-20), with U_test's capability ranges."""
RETURNED_LOG = "log.txt"
"""The script's stdout as the Robotarium returns it (beside the data files the run wrote)."""
SEED_RUN_STRIDE = 100
"""Folder (size, run) is exported with seed ``seed + SEED_RUN_STRIDE · run + size`` (sizes < 100)."""
MAX_RUNS = 100
"""Runs per size at most (a campaign of more is a typo, and the seeds above stay distinct)."""


class CampaignError(ValueError):
    """A campaign's arguments, manifest or returned folder that cannot be used (one line naming the
    argument, what it takes and what it got)."""


def parse_sizes(value: str | Sequence[int]) -> list[int]:
    """``--sizes``: ``"4,8,12,20"`` (or a sequence) as distinct robot counts 1..20, in the given order."""
    items = value.split(",") if isinstance(value, str) else list(value)
    try:
        sizes = [int(str(s).strip()) for s in items]
    except ValueError:
        raise CampaignError(
            f"--sizes must be robot counts separated by commas (e.g. 4,8,12,20), got {value!r}"
        ) from None
    if not sizes or any(not 1 <= s <= 20 for s in sizes) or len(set(sizes)) != len(sizes):
        raise CampaignError(f"--sizes must be distinct robot counts of 1..20 (the Robotarium's limit), got {value!r}")
    return sizes


def parse_sets(value: str | Sequence[str]) -> list[str]:
    """``--sets``: composition sets by name (``test``) or report name (``U_test``), in the given order."""
    items = value.split(",") if isinstance(value, str) else list(value)
    by_label = {label: name for name, label in SET_LABELS.items()}
    sets = [by_label.get(s.strip(), s.strip()) for s in items]
    bad = [s for s in sets if s not in COALITION_SETS]
    if not sets or bad or len(set(sets)) != len(sets):
        raise CampaignError(
            f"--sets must be distinct composition sets of {list(COALITION_SETS)} (or {list(SET_LABELS.values())}), "
            f"got {value!r}"
        )
    return sets


def folder_name(task: str, size: int, run: int) -> str:
    """The submission folder of run ``run`` with ``size`` robots: ``pcp_n04_r00``."""
    return f"{task}_n{size:02d}_r{run:02d}"


def plan_teams(task: str, sizes: Sequence[int], runs: int, sets: Sequence[str], seed: int) -> list[dict]:
    """Which team each (size, run) plays: ``[{"size", "run", "team" ("set:K"), "robots" (TeamSpec)}]``
    in size order, then run order (module docstring: Teams)."""
    if isinstance(runs, bool) or not isinstance(runs, int) or not 1 <= runs <= MAX_RUNS:
        raise CampaignError(f"--runs must be an integer of 1..{MAX_RUNS} (runs per team size), got {runs!r}")
    pool = [(s, k, team) for s in sets for k, team in enumerate(resolve_coalitions(s, task))]
    plan = []
    for size in sizes:
        mine = [(s, k, team) for s, k, team in pool if team.size == size]
        if not mine:
            have = sorted({team.size for _, _, team in pool})
            labels = ", ".join(SET_LABELS[s] for s in sets)
            raise CampaignError(f"--sizes: task {task!r} has no team of {size} robots in {labels}; sizes there: {have}")
        order = np.random.default_rng([int(seed), int(size)]).permutation(len(mine))
        for run in range(runs):
            s, k, team = mine[int(order[run % len(mine)])]
            plan.append({"size": size, "run": run, "team": f"{s}:{k}", "robots": team})
    return plan


def make_campaign(
    policy: str,
    task: str,
    sizes: Sequence[int],
    runs: int,
    out: str | Path,
    sets: Sequence[str] = DEFAULT_SETS,
    seed: int = 0,
    policy_label: str | None = None,
    filter_name: str = "comat",
    filter_reality: str = "nominal",
) -> dict:
    # long: writes every folder of the campaign and its manifest inside one atomic temporary folder
    """Write the campaign's folders and manifest in ``out`` (module docstring); returns the manifest.

    Args:
        policy: what :func:`sim2real.export.export_submission` takes: a COMAT checkpoint or policy
            file's path, or ``"heuristic"``.
        task, sizes, runs, sets, seed: see the module docstring.
        policy_label: how the manifest names the policy (default ``policy``), e.g. ``pretrained:comat-pcp``.
        filter_name, filter_reality: the exported loop's filter (:func:`~sim2real.export.export_submission`).
    """
    out = Path(out)
    if out.exists():
        raise CampaignError(f"--out {str(out)!r} already exists; choose a new folder")
    sizes, sets = parse_sizes(sizes), parse_sets(sets)
    plan = plan_teams(task, sizes, runs, sets, seed)  # before anything is written
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.tmp-", dir=out.parent))
    try:
        entries = []
        for item in plan:
            name = folder_name(task, item["size"], item["run"])
            folder_seed = int(seed) + SEED_RUN_STRIDE * item["run"] + item["size"]
            export_submission(
                policy,
                task,
                item["robots"],
                tmp / name,
                seed=folder_seed,
                filter_name=filter_name,
                filter_reality=filter_reality,
            )
            config = load_config(tmp / name)
            entries.append(
                {
                    "folder": name,
                    "size": item["size"],
                    "run": item["run"],
                    "team": item["team"],
                    "types": config["types"],
                    "capabilities": config["capabilities"],
                    "seed": folder_seed,
                    "robots": config["robots"],
                    "duration_s": config["duration_s"],
                    "horizon_s": config["horizon_s"],
                    "startup_drive_s": config["startup_drive_s"],
                    "policy_sha256": config["policy_sha256"],
                }
            )
        manifest = {
            "format": MANIFEST_FORMAT,
            "version": MANIFEST_VERSION,
            "task": task,
            "policy": policy_label or str(policy),
            "policy_sha256": entries[0]["policy_sha256"],
            "comat_version": config["comat_version"],
            "comat_commit": source_commit(),
            "seed": int(seed),
            "sizes": sizes,
            "runs": runs,
            "sets": sets,
            "filter": config["filter"],
            "filter_reality": config.get("filter_reality"),
            "folders": entries,
        }
        write_atomic(tmp / MANIFEST_FILE, json.dumps(manifest, indent=1) + "\n")
        write_atomic(tmp / MANIFEST_MD, manifest_markdown(manifest))
        tmp.chmod(0o755)
        tmp.rename(out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return manifest


def declarations(manifest: dict) -> list[str]:
    """One line per folder: what to declare on the Robotarium's form."""
    return [
        f"{e['folder']}: declare {e['duration_s']} s and {e['robots']} robots (team {e['team']}, seed {e['seed']})"
        for e in manifest["folders"]
    ]


def manifest_markdown(manifest: dict) -> str:
    """``manifest.md``: the campaign for a person (what to submit, declare and bring back)."""
    total = sum(e["duration_s"] for e in manifest["folders"])
    made_for = f" (made for {manifest['filter_reality']})" if manifest["filter_reality"] else ""
    lines = [
        f"# Campaign: {manifest['policy']} on {manifest['task']}",
        "",
        (
            f"{len(manifest['folders'])} experiments: sizes {manifest['sizes']} × {manifest['runs']} runs, teams "
            f"from {', '.join(SET_LABELS[s] for s in manifest['sets'])} (seed {manifest['seed']}); policy sha256 "
            f"`{manifest['policy_sha256']}`; comat {manifest['comat_version']} at `{manifest['comat_commit']}`; "
            f"filter {manifest['filter']}{made_for}."
        ),
        f"Declared time in all: {total} s ({total / 60:.0f} min).",
        "",
        (
            "Submit each folder as one experiment: upload its files, mark `main.py` as main, declare the duration "
            "and robots below, and list `comat_run.npy` and `comat_run.meta.npy` as the data files to return. Bring "
            "every experiment's download back into one folder, a subfolder per experiment named as below "
            "(`log.txt`, `comat_run.npy`, `comat_run.meta.npy`; the scripts and the video may stay), an empty "
            "subfolder for an experiment that never ran, then: "
            "`comat campaign --analyze RETURNED --manifest manifest.json --out OUT`."
        ),
        "",
        "| folder | robots | team | seed | declare (s) | episode up to (s) | start-up drive up to (s) |",
        "|---|---|---|---|---|---|---|",
    ]
    lines += [
        f"| {e['folder']} | {e['robots']} | {e['team']} | {e['seed']} | {e['duration_s']} | {e['horizon_s']:.0f} | "
        f"{e['startup_drive_s']:.0f} |"
        for e in manifest["folders"]
    ]
    return "\n".join(lines) + "\n"


_ENTRY_KEYS = ("folder", "size", "run", "team", "types", "capabilities", "seed", "robots", "duration_s")


def read_manifest(path: str | Path) -> dict:
    """A campaign's ``manifest.json`` (CampaignError naming ``--manifest``, what it expects and what it got)."""
    path = Path(path)
    if not path.is_file():
        raise CampaignError(f"--manifest must be a campaign's {MANIFEST_FILE}, got {str(path)!r} (no such file)")
    try:
        manifest = json.loads(path.read_bytes().decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as err:
        raise CampaignError(f"--manifest {str(path)!r} must be JSON, got a file that is not ({err})") from None
    got = manifest.get("format") if isinstance(manifest, dict) else type(manifest).__name__
    if got != MANIFEST_FORMAT:
        raise CampaignError(f"--manifest {str(path)!r}: expected format {MANIFEST_FORMAT!r}, got {got!r}")
    if manifest.get("version") != MANIFEST_VERSION:
        raise CampaignError(
            f"--manifest {str(path)!r}: expected version {MANIFEST_VERSION}, got {manifest.get('version')!r}"
        )
    folders = manifest.get("folders")
    if not isinstance(folders, list) or not folders:
        raise CampaignError(f"--manifest {str(path)!r}: expected a non-empty list of folders, got {folders!r:.80}")
    for i, e in enumerate(folders):
        missing = [k for k in _ENTRY_KEYS if not isinstance(e, dict) or k not in e]
        if missing:
            raise CampaignError(f"--manifest {str(path)!r}: folders[{i}] lacks {missing}")
    for e in folders:
        if not (path.parent / e["folder"] / "submission_config.py").is_file():
            raise CampaignError(
                f"--manifest {str(path)!r}: expected its submission folder {e['folder']} beside it "
                "(the twin replays that folder's policy), got none"
            )
    return manifest


def stand_in_returns(
    manifest_path: str | Path,
    returned: str | Path,
    reality: str | None = None,
    drive: str = "rps",
    max_steps: int | None = None,
    rps_path: str | None = None,
    timeout_s: float = 1800.0,
) -> list[Path]:
    """What the Robotarium would return for every folder of a campaign, made here: each folder's
    ``main.py`` run under ``rps`` (:func:`sim2real.check.run_rps`, run r of a size with layer seed r
    at ``reality``), its ``comat_run.npy`` and ``comat_run.meta.npy`` and its stdout as
    :data:`RETURNED_LOG` put in ``returned/<folder>/`` (written atomically: all or nothing).
    ``max_steps``: stop each run after that many env steps (a quick rehearsal)."""
    manifest_path, returned = Path(manifest_path), Path(returned)
    manifest = read_manifest(manifest_path)
    if returned.exists():
        raise CampaignError(f"--out {str(returned)!r} already exists; choose a new folder")
    returned.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{returned.name}.tmp-", dir=returned.parent))
    try:
        work = tmp / ".work"  # the folders run from a copy: their logs land beside the copy
        for e in manifest["folders"]:
            copy = shutil.copytree(manifest_path.parent / e["folder"], work / e["folder"])
            try:
                result = run_rps(
                    copy, timeout_s, rps_path, max_steps=max_steps, reality=reality, seed=e["run"], drive=drive
                )
            except CheckError as err:  # named by the campaign's folder, not the copy that ran
                raise CheckError(str(err).replace(str(copy), str(manifest_path.parent / e["folder"]))) from None
            dest = tmp / e["folder"]
            dest.mkdir()
            for name in (LOG_FILE, META_FILE):
                shutil.move(str(Path(result["run_log"]) / name), dest / name)
            (dest / RETURNED_LOG).write_text(result["stdout"] + "\n")
        shutil.rmtree(work)
        tmp.chmod(0o755)
        tmp.rename(returned)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return [returned / e["folder"] for e in manifest["folders"]]
