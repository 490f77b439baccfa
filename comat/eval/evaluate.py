"""``comat eval``: a checkpoint (and reference policies) on the training and unseen coalitions.

Protocol: for each set (U_train, U_test; 20 coalitions each), ``episodes`` episodes per
coalition with deterministic actions, environments seeded from ``seed``; the same teams and
starts for every policy. Rows: the checkpoint's policy, the scripted heuristic (privileged: it
reads the task state), the best constant action (every robot always the same waypoint step:
what a policy that ignores its observations can reach) and uniformly random actions. Each metric of
:data:`REPORTED` comes with
a 95 % confidence interval over the coalitions (each coalition's episodes averaged first:
:func:`comat.measure.metrics.summarize_ci`). Every episode row keeps its progress curve, endpoints
and per-robot diagnostics (:func:`comat.measure.episodes.run_episodes`).

Reality: every policy plays at one reality layer (:mod:`comat.reality`; default ``off``, the
ideal world, whatever level the policy trained at), the same teams and starts at every level
(paired episodes). Rows say it (``"reality"``: the level's name, or ``"custom"`` for a level with
fields changed); the result holds the resolved layer (``"reality_config"``).

Outputs (``--out``, :func:`write_results`): ``<stem>.json`` (every row with means and intervals),
``<stem>.episodes.json.gz`` (the rows' per-episode metrics, gzipped: read both with
:func:`comat.measure.metrics.read_results`) and ``<stem>.csv`` (one line per row and metric), all
written atomically.
"""

from __future__ import annotations

import copy
import csv
import io
import re
import textwrap
import time
from collections.abc import Callable
from pathlib import Path

from comat.envs import make_vec_env
from comat.envs.base import resolve_coalitions
from comat.envs.heuristics import LADDER, RUNG_ALIASES, has_blind, reference_policy
from comat.files import detail_name, relative_path, write_atomic, write_json_detail
from comat.measure.episodes import run_episodes
from comat.measure.metrics import REPORTED, SHARES, interval_text, summarize_ci
from comat.reality import resolve_reality
from comat.rl import BASELINE_ROBOTS, load_policy, robot_slots
from comat.task_logic import TaskLogic
from comat.tasks import env_id, task_entry, task_names
from comat.team import COALITION_SETS

__all__ = [
    "EVAL_SEED",
    "REFERENCES",
    "TABLE_NAMES",
    "evaluate_policies",
    "print_table",
    "result_files",
    "table_lines",
    "write_results",
]

EVAL_SEED = 2_000_003
"""Default seed of evaluation episodes (never a training seed of the presets)."""
SETS = COALITION_SETS


def _policies(config, checkpoint_act, env, seed: int, split: str, teams) -> dict[str, Callable]:
    """The checkpoint's policy (when given) and every rung of the reference ladder on ``env``."""
    out = {}
    if checkpoint_act is not None:
        out[config.algo] = checkpoint_act
    ours = {"split": split, "teams": None} if split in SETS else {"split": None, "teams": teams}
    for name in REFERENCES:
        if name != "blind" or has_blind(env.task):
            out[name] = reference_policy(name, env.core, seed, **ours)
    return out


REFERENCES = LADDER
"""Reference rows, in table order: the ladder (:mod:`comat.envs.heuristics`): heuristic (the scripted
rung), type_only, blind (where the task has one), constant, random."""


_REFERENCE_EPISODES: dict[tuple, list[dict]] = {}
"""A reference rung's episodes, by everything they depend on (task, set and its teams, episodes,
tier, seed, reality layer, filter, the env's robot slots, rung): the ladder is deterministic, so a
process that evaluates several policies on the same sets (a notebook, a report, ``comat eval`` of a
run after the shipped policy) plays each rung once. At most :data:`REFERENCE_MEMORY` entries."""
REFERENCE_MEMORY = 64


def _remember_reference(key: tuple, episodes: list[dict]) -> None:
    if len(_REFERENCE_EPISODES) >= REFERENCE_MEMORY:
        _REFERENCE_EPISODES.pop(next(iter(_REFERENCE_EPISODES)))  # the oldest first
    _REFERENCE_EPISODES[key] = episodes


def evaluate_policies(
    checkpoint: str | Path | None,
    task: str | None = None,
    sets=SETS,
    episodes: int = 1,
    tier: str | None = None,
    seed: int = EVAL_SEED,
    references: bool | tuple[str, ...] = True,
    progress=print,
    reality="off",
    safety=None,
) -> dict:
    # long: checks its arguments, then one loop over (set, policy) rows and the document they make
    """Rows of (policy, set) results; see the module docstring.

    Args:
        checkpoint: a run's ``checkpoint.pt`` (or None: reference policies on ``task`` only).
        task: the task (taken from the checkpoint when given; must match it).
        sets: any of "train", "test", "scale", or ``(name, teams)`` pairs (a set of one's own:
            its rows carry ``"set": name``).
        episodes: episodes per coalition (>= 1).
        tier: dynamics tier (default: the checkpoint's training tier, else unicycle).
        references: add every rung of the reference ladder (True: heuristic, type_only, blind,
            constant, random), none (False), or those named (``scripted`` for the heuristic).
        reality: the reality layer every policy plays at: ``"off"`` (default, whatever the
            checkpoint trained at), ``"nominal"``, ``"stress"``, a RealityConfig or a mapping of
            its fields (:func:`comat.reality.resolve_reality`).
        safety: the barrier filter's :class:`~comat.config.SafetyConfig` (default: the envs'),
            e.g. ``SafetyConfig(robust=False)`` to measure what the reality margin costs.
    """
    import dataclasses

    if isinstance(episodes, bool) or not isinstance(episodes, int) or episodes < 1:
        raise ValueError(f"episodes must be an integer >= 1 (per coalition), got {episodes!r}")
    sets = list(sets)
    bad = [s for s in sets if not (s in SETS or (isinstance(s, tuple) and len(s) == 2 and s[1]))]
    if bad or not sets:
        raise ValueError(f"sets must be a non-empty list of {list(SETS)} or (name, teams) pairs, got {sets!r:.200}")
    refs = REFERENCES if references is True else tuple(RUNG_ALIASES.get(r, r) for r in references or ())
    if any(r not in REFERENCES for r in refs):
        raise ValueError(f"references must be True, False or names from {REFERENCES}, got {references!r}")
    layer = resolve_reality(reality, "reality")
    level = layer.label
    act, config = (None, None)
    if checkpoint is not None:
        act, config = load_policy(checkpoint, task=task)
        task = config.task
    elif task not in task_names():
        raise ValueError(f"task must be one of {list(task_names())} when no checkpoint is given, got {task!r}")
    tier = tier or (config.tier if config else "unicycle")
    if tier not in ("wheels", "unicycle"):
        raise ValueError(f"tier must be 'wheels' or 'unicycle', got {tier!r}")
    slots = None if config is None else robot_slots(config)
    named = [
        (s, resolve_coalitions(s, task)) if isinstance(s, str) else (s[0], resolve_coalitions(list(s[1]), task))
        for s in sets
    ]
    largest = {split: max(t.size for t in teams) for split, teams in named}
    too_large = [s for s, _ in named if slots is not None and largest[s] > slots]
    if too_large:
        raise ValueError(
            f"sets {too_large} hold teams of up to {max(largest[s] for s in too_large)} robots, but this "
            f"{config.algo} checkpoint has {slots} robot slots (fixed-size: train it with "
            f"models.{config.algo}.max_robots=20 to play U_scale)"
        )
    rows = []
    for split, coalitions in named:
        teams = coalitions * episodes
        # One process: the heuristic reads the env's task state directly.
        env = make_vec_env(
            env_id(task),
            min(len(teams), 32),
            seed=seed,
            tier=tier,
            coalitions=coalitions,
            max_robots=slots,
            state_robots=slots or BASELINE_ROBOTS,
            reality=layer,
            safety=safety,
        )
        policies = _policies(config, act, env, seed, split, coalitions)
        policies = {k: v for k, v in policies.items() if k not in REFERENCES or k in refs}
        played = (task, split, repr(coalitions), episodes, tier, seed, repr(layer), repr(safety), slots)
        for name, policy in policies.items():
            t0 = time.perf_counter()
            key = (*played, name) if name in REFERENCES else None
            again = key in _REFERENCE_EPISODES
            eps = copy.deepcopy(_REFERENCE_EPISODES[key]) if again else None
            if eps is None:
                eps = run_episodes(env, policy, teams, seed, n_coalitions=len(coalitions))
                if key is not None:
                    _remember_reference(key, copy.deepcopy(eps))
            rows.append(
                {
                    "policy": name,
                    "task": task,
                    "set": split,
                    "tier": tier,
                    "reality": level,
                    "episodes": len(eps),
                    "metrics": summarize_ci(eps),
                    "per_episode": eps,
                }
            )
            took = "played earlier in this process" if again else f"in {time.perf_counter() - t0:.0f} s"
            progress(f"  {name:<10} {split:<5} {len(eps)} episodes {took}")
    return {
        "checkpoint": None if checkpoint is None else str(checkpoint),
        "algo": None if config is None else config.algo,
        "trained_tier": None if config is None else config.tier,
        "trained_reality": None if config is None else config.reality.label,
        "task": task,
        "env_id": env_id(task),
        "tier": tier,
        "seed": seed,
        "episodes_per_coalition": episodes,
        "reality": level,
        "reality_config": dataclasses.asdict(layer),
        "loop": "comat" if safety is None else safety.loop,
        "trained_loop": None if config is None else config.loop,
        "rows": rows,
    }


TABLE_NAMES = {
    "return": "return",
    "steps": "steps",
    "progress": "progress",
    "finished": "finished",
    "progress_auc": "AUC",
    "time_to_90": "t90",
    "coordination": "coord.",
    "collisions": "collisions",
    "violations": "violations",
    "interventions": "interv.",
    "fallbacks": "fallbacks",
    "recoveries": "recoveries",
}
"""Column name of each metric of :data:`REPORTED` in :func:`print_table`."""


TABLE_GAP = "  "
"""What separates two columns of :func:`table_lines`."""


OUTCOMES = REPORTED[: REPORTED.index("coordination") + 1]
"""The task's metrics: the table :func:`print_table` shows first."""
SAFETY_METRICS = REPORTED[len(OUTCOMES) :]
"""Collisions, violations and the filter's work: the second table, without the columns that are 0 in every row."""
FOOTER_WIDTH = 120
"""Characters per line of the notes under :func:`print_table`'s tables."""
PRIVILEGED = ("heuristic", "type_only", "blind")
"""Reference rungs that read the full task state (:mod:`comat.envs.heuristics`): their rows are
privileged references, which :func:`print_table` says."""


def table_lines(result: dict, metrics: tuple[str, ...] = REPORTED) -> list[str]:
    """The rows as a fixed-width table of ``metrics`` (:func:`print_table`): each column as wide as
    its widest cell (header included), columns two spaces apart, so none ever touch (an interval
    written ``mean [low, high]`` is wider than ``mean ± half``)."""
    heads = ["policy", "set", "n", *(TABLE_NAMES[m] for m in metrics)]
    left = (True, True, False, *(False for _ in metrics))
    rows = []
    for r in result["rows"]:
        cells = [str(r["policy"]), str(r["set"]), str(r["episodes"])]
        for m in metrics:
            v = r["metrics"].get(m)
            cells.append("n/a" if v is None else interval_text(v["mean"], v["ci95"], share=m in SHARES, unit=None))
        rows.append(cells)
    widths = [max(len(c[j]) for c in [heads, *rows]) for j in range(len(heads))]

    def line(cells: list[str]) -> str:
        return TABLE_GAP.join(c.ljust(w) if lj else c.rjust(w) for c, w, lj in zip(cells, widths, left)).rstrip()

    head = line(heads)
    return [head, "-" * len(head), *(line(c) for c in rows)]


def _own_sentence(logic: type | None, method: str) -> str:
    """The first sentence of ``logic``'s own docstring of ``method`` (not a base class's generic
    one), shape notes such as "(B,)" dropped, lower-cased at its start; "" without one."""
    fn = getattr(logic, method, None)
    if fn is None or fn is getattr(TaskLogic, method, None) or not fn.__doc__:
        return ""
    text = " ".join(fn.__doc__.split())
    sentence = re.split(r"(?<=[.!?]) ", text, maxsplit=1)[0].rstrip(".")
    sentence = re.sub(r" ?\(B(?:, N)?,?\)", "", sentence).strip()
    # "Fraction ..." -> "fraction ...", an initialism ("HMT ...") kept.
    return sentence[:1].lower() + sentence[1:] if sentence[1:2].islower() else sentence


def task_legend(task: str | None) -> list[str]:
    """What progress, finished and coord. mean for ``task``, one line each, read from its registered
    logic class (:func:`comat.tasks.task_entry`): the first sentence of its ``progress`` and ``done``
    docstrings, its ``coordination_name`` and ``coordination_doc``; general words for a task not
    registered here (a plugin not loaded) or a docstring it lacks."""
    try:
        logic = task_entry(task).logic
    except ValueError:
        logic = None
    progress = _own_sentence(logic, "progress") or "the task's share of its work done"
    done = _own_sentence(logic, "done")
    name, doc = getattr(logic, "coordination_name", ""), getattr(logic, "coordination_doc", "")
    label = task or "the task"
    finished = "share of episodes done before the horizon" + (f": {done}" if done else "")
    coord = f"{name}: {doc or 'its mean over the episode'}" if name else f"n/a ({label} has no coordination metric)"
    return [
        f"progress ({label}) = {progress}",
        f'finished = {finished} (the paper\'s "completion")',
        f"coord. = {coord}",
    ]


def _always_zero(result: dict, metric: str) -> bool:
    values = [r["metrics"].get(metric) for r in result["rows"]]
    return bool(values) and all(v is not None and v["mean"] == 0 and v["ci95"] == 0 for v in values)


def print_table(result: dict, out=print) -> None:
    """The rows as two fixed-width tables (:func:`table_lines`) of ``mean ± 95 % CI`` (over
    coalitions), each under ~130 characters: the task's metrics (:data:`OUTCOMES`), then collisions,
    violations and the filter's work (:data:`SAFETY_METRICS`) less the columns that are 0 in every
    row, which one line names. "n/a" for a metric a row lacks (a file written before the metric
    existed, or a task without a coordination metric). Under them, a few short lines: what the
    columns mean for the task at hand (:func:`task_legend`), that the scripted rungs read the task's
    full state, the interval, the reality layer and the start states."""
    zero = [m for m in SAFETY_METRICS if _always_zero(result, m)]
    shown = tuple(m for m in SAFETY_METRICS if m not in zero)
    for i, metrics in enumerate((OUTCOMES, shown) if shown else (OUTCOMES,)):
        lines = table_lines(result, metrics)
        out(("\n" if i else "") + "\n".join(lines[:2]))
        for text in lines[2:]:
            out(text)
    k = result.get("episodes_per_coalition", 1)
    notes = list(task_legend(result.get("task")))
    if zero:
        notes.append(f"0 in every row: {', '.join(TABLE_NAMES[m] for m in zero)} (the JSON and CSV hold every column)")
    scripted = [p for p in dict.fromkeys(r["policy"] for r in result["rows"]) if p in PRIVILEGED]
    if scripted:
        notes.append(
            f"{', '.join(scripted)}: the scripted planner, reading the task's full state: privileged references, "
            "not rivals on equal terms"
        )
    notes.append(
        "AUC = mean progress over the horizon's env steps (the last value held after an early finish); "
        "t90 = env steps to 90 % progress (the horizon if never)"
    )
    # Old result files predate the layer (their episodes were all in the ideal world).
    if "reality" in result:
        notes.append(f"reality layer {result['reality']} (comat eval --reality)")
    notes.append(
        f"n = episodes ({k} per coalition); ± = 95 % t-interval over the coalitions' means (each coalition's {k} "
        "episode(s) averaged first); [low, high]: a share's interval cut to [0, 1]; none with one coalition; "
        "one policy: seed-to-seed spread is not in it"
    )
    if "seed" in result:
        notes.append(
            f"start states: drawn from seed {result['seed']} (comat eval --seed), the same teams and starts for every "
            "policy here; training's evaluations draw theirs from the run's seed + 1,000,003: other starts, other "
            "numbers"
        )
    out("")
    for note in notes:  # each note a line, wrapped to the tables' width
        for text in textwrap.wrap(note, FOOTER_WIDTH, subsequent_indent="  "):
            out(text)


def result_files(stem: str) -> list[str]:
    """The files :func:`write_results` writes for ``stem`` (what ``--out`` checks before a run)."""
    return [f"{stem}.json", detail_name(f"{stem}.json"), f"{stem}.csv"]


def write_results(result: dict, out_dir: str | Path, stem: str = "eval") -> list[Path]:
    """:func:`result_files` in ``out_dir`` (which must exist), atomically: ``<stem>.json`` the
    summary (every row with its metrics and intervals), ``<stem>.episodes.json.gz`` the rows'
    per-episode detail (:func:`comat.files.write_json_detail`; read both back with
    :func:`comat.measure.metrics.read_results`) and ``<stem>.csv`` one line per row and metric.
    ``"checkpoint"`` is written relative to ``out_dir``."""
    out_dir = Path(out_dir)
    if not out_dir.is_dir():
        raise FileNotFoundError(f"output folder {str(out_dir)!r} does not exist")
    buf = io.StringIO()
    writer = csv.writer(buf)
    writer.writerow(["policy", "task", "set", "tier", "episodes", "metric", "mean", "ci95"])
    for r in result["rows"]:
        for m in (m for m in REPORTED if m in r["metrics"]):
            writer.writerow(
                [
                    r["policy"],
                    r["task"],
                    r["set"],
                    r["tier"],
                    r["episodes"],
                    m,
                    r["metrics"][m]["mean"],
                    r["metrics"][m]["ci95"],
                ]
            )
    if result.get("checkpoint") is not None:
        result = {**result, "checkpoint": relative_path(result["checkpoint"], out_dir)}
    paths = write_json_detail(out_dir / f"{stem}.json", result)
    write_atomic(out_dir / f"{stem}.csv", buf.getvalue())
    return [*paths, out_dir / f"{stem}.csv"]
