"""Team compositions: robots with a type and a capability vector, teams, and the composition sets.

A task's module states its robot types, capability names and limits, and the capability bands
and random streams of its sets (:mod:`comat.tasks`; :data:`TASK_TYPES` and
:data:`CAPABILITY_RANGES` read them from the registered tasks). A robot is a
``RobotSpec(type, capabilities)``; a team is a ``TeamSpec(task, robots)`` with at least one robot
of each type. The composition sets are generated from a seed by :func:`generate_coalitions` — the
envs use that function, so the code is the source of these sets — and stored as YAML in
:data:`COALITIONS_DIR` (inside the package, linked from the checkout as ``train/coalitions/``;
``comat coalitions`` regenerates them, a test checks they match). Each set holds 20 coalitions per
task and draws from its own random stream, so adding a set changes no other set's teams. The
sets (:data:`COALITION_SETS`; report names in :data:`SET_LABELS`):

* ``train`` (U_train, the paper §III-D): team sizes drawn from {3, 5, 7}, the *training* ranges.
* ``val`` (U_val): drawn exactly like U_train (sizes {3, 5, 7}, training ranges) from another
  stream, and no team equal to a U_train team (same robots in any order). The only set model
  selection or tuning may look at: U_test, U_scale, U_size and U_cap stay unseen.
* ``test`` (U_test, the paper §III-D): sizes drawn from {2, 4, 6, 8}, the paper's *unseen* ranges
  (they overlap the training ranges: many of its robots are not novel).
* ``scale`` (U_scale): sizes drawn from {10, 12, 16, 20}, U_test's ranges: past the 8 slots of the
  paper's baselines up to the Robotarium's 20 robots. Changes size and capability together.
* ``size`` (U_size): two teams of each size 2, 4, …, 20 (listed by size), the *training* ranges:
  team size is the only thing that differs from U_train.
* ``capability`` (U_cap): sizes drawn from {3, 5, 7} like U_train, and every robot's every
  capability the task uses lies *outside* its type's training range — below it or above it, each
  side drawn with probability proportional to its band's width (so uniform over the union of the
  two bands), inside the physical limits: capability is the only thing that differs from U_train.

Each task's spec sheet gives its sets' capability ranges (e.g. :mod:`comat.tasks.pcp`). U_val
and U_size draw from the training bands, U_scale from the test ones.

Capabilities are rounded to 1e-6 (what the files hold); U_cap's bands stop one such step short of
the training range, so a rounded value never lands on its edge.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from comat.tasks import COALITION_SETS, TASKS, Band, TaskTypes

COALITIONS_DIR = Path(__file__).resolve().parent / "data" / "coalitions"
"""The stored copies ``<task>_<set>.yaml`` of the composition sets, shipped in the package so an
installed comat has them to read and to pass as ``coalitions=PATH``."""

__all__ = [
    "CAPABILITY_RANGES",
    "COALITIONS_DIR",
    "COALITION_SETS",
    "SET_LABELS",
    "SIZES",
    "TASK_TYPES",
    "Band",
    "RobotSpec",
    "TaskTypes",
    "TeamSpec",
    "generate_coalitions",
    "load_coalitions",
    "load_team",
    "random_team",
    "save_coalitions",
]


class _TaskTypes(Mapping):
    """task -> :class:`~comat.tasks.TaskTypes`, read from the registered tasks (:mod:`comat.tasks`)."""

    def __getitem__(self, task: str) -> TaskTypes:
        if task not in TASKS:
            raise KeyError(task)
        return TASKS[task].types

    def __iter__(self):
        return iter(TASKS)

    def __len__(self) -> int:
        return len(TASKS)


TASK_TYPES: Mapping[str, TaskTypes] = _TaskTypes()
"""Each registered task's robot types and capability layout (its module states them)."""

SIZES = {
    "train": (3, 5, 7),
    "val": (3, 5, 7),
    "test": (2, 4, 6, 8),
    "scale": (10, 12, 16, 20),
    "size": tuple(range(2, 21, 2)),
    "capability": (3, 5, 7),
}
"""Team sizes of each composition set. U_scale goes past the 8 slots of the paper's baselines up to the
Robotarium's 20 robots, with U_test's capability ranges: the sizes where fixed-slot methods stop.
U_size lists each of its sizes equally often instead of drawing them (see :func:`generate_coalitions`)."""

SET_LABELS = {
    "train": "U_train",
    "val": "U_val",
    "test": "U_test",
    "scale": "U_scale",
    "size": "U_size",
    "capability": "U_cap",
}
"""Report and display name of each set."""

_GRAIN = 1e-6
"""Capabilities are rounded to this (what the YAML files hold)."""


class _CapabilityRanges(Mapping):
    """(task, set) -> type -> per capability, the bands its values are drawn from: uniform over their
    union (a band chosen with probability proportional to its width, then uniform inside it). One
    band for every set but U_cap. Read from the registered tasks (each task's ``capability_bands``)."""

    def __getitem__(self, key: tuple[str, str]) -> dict[str, tuple[tuple[Band, ...], ...]]:
        task, split = key
        if task not in TASKS or split not in COALITION_SETS:
            raise KeyError(key)
        return dict(TASKS[task].bands[split])

    def __iter__(self):
        return iter([(task, split) for task in TASKS for split in COALITION_SETS])

    def __len__(self) -> int:
        return len(TASKS) * len(COALITION_SETS)


CAPABILITY_RANGES: Mapping[tuple[str, str], dict[str, tuple[tuple[Band, ...], ...]]] = _CapabilityRanges()
"""(task, set) -> type -> per capability, its bands (see :class:`_CapabilityRanges`)."""


@dataclass(frozen=True)
class RobotSpec:
    """One robot: its type (a name of the task's types) and capability vector."""

    type: str
    capabilities: tuple[float, ...]

    def to_dict(self) -> dict[str, Any]:
        return {"type": self.type, "capabilities": [float(c) for c in self.capabilities]}


@dataclass(frozen=True)
class TeamSpec:
    """A team for one task: robots in order (robot_i is ``robots[i]``).

    Raises ValueError (naming the robot, the expected and the received value) for an unknown
    task or type, a capability vector of the wrong length, capabilities outside the physical
    limits or not positive where the type's role needs them, an empty team, or a team missing
    one of the task's types.
    """

    task: str
    robots: tuple[RobotSpec, ...]

    def __post_init__(self) -> None:
        if self.task not in TASK_TYPES:
            raise ValueError(f"team task must be one of {sorted(TASK_TYPES)}, got {self.task!r}")
        tt = TASK_TYPES[self.task]
        if len(self.robots) == 0:
            raise ValueError(f"a {self.task} team needs at least one robot of each type {tt.needed}, got an empty team")
        for i, r in enumerate(self.robots):
            if r.type not in tt.types:
                raise ValueError(f"robot {i}: type must be one of {tt.types} for {self.task}, got {r.type!r}")
            if len(r.capabilities) != len(tt.capabilities):
                raise ValueError(
                    f"robot {i}: capabilities must be {len(tt.capabilities)} numbers {tt.capabilities}, "
                    f"got {list(r.capabilities)}"
                )
            for k, (name, (lo, hi)) in enumerate(zip(tt.capabilities, tt.limits)):
                value = r.capabilities[k]
                if not (np.isfinite(value) and lo <= value <= hi):
                    raise ValueError(f"robot {i}: {name} must be in [{lo}, {hi}] (physical limit), got {value}")
            for k in tt.required[tt.types.index(r.type)]:
                if r.capabilities[k] <= 0:
                    raise ValueError(
                        f"robot {i}: a {r.type} robot needs {tt.capabilities[k]} > 0, got {r.capabilities[k]}"
                    )
            for k in tt.ignored[tt.types.index(r.type)] if tt.ignored else ():
                if r.capabilities[k] != 0:
                    raise ValueError(
                        f"robot {i}: a {r.type} robot has no {tt.capabilities[k]} (the {self.task} rules ignore it); "
                        f"expected 0, got {r.capabilities[k]}"
                    )
        missing = [t for t in tt.needed if all(r.type != t for r in self.robots)]
        if missing:
            raise ValueError(f"a {self.task} team needs at least one robot of each type {tt.needed}; missing {missing}")

    @property
    def size(self) -> int:
        return len(self.robots)

    def type_ids(self) -> np.ndarray:
        """(N,) index of each robot's type in the task's type list."""
        types = TASK_TYPES[self.task].types
        return np.array([types.index(r.type) for r in self.robots], dtype=np.int64)

    def capability_array(self) -> np.ndarray:
        """(N, C) capability vectors."""
        return np.array([r.capabilities for r in self.robots], dtype=np.float64)

    def to_dict(self) -> dict[str, Any]:
        return {"task": self.task, "robots": [r.to_dict() for r in self.robots]}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> TeamSpec:
        """Build from ``{"task": ..., "robots": [{"type": ..., "capabilities": [...]}, ...]}``."""
        if not isinstance(data, Mapping) or set(data) - {"task", "robots"} or "robots" not in data:
            raise ValueError(f"team must be a mapping with keys 'task' and 'robots', got {data!r}")
        robots = data["robots"]
        if not isinstance(robots, Sequence) or isinstance(robots, str):
            raise ValueError(f"team robots must be a list, got {robots!r}")  # noqa: TRY004
        specs = []
        for i, r in enumerate(robots):
            if not isinstance(r, Mapping) or set(r) != {"type", "capabilities"}:
                raise ValueError(f"team robot {i} must have exactly the keys 'type' and 'capabilities', got {r!r}")
            specs.append(RobotSpec(str(r["type"]), tuple(float(c) for c in r["capabilities"])))
        return cls(str(data.get("task", "")), tuple(specs))


def _draw(rng: np.random.Generator, bands: tuple[Band, ...]) -> float:
    """One value uniform over the union of ``bands``, rounded to 1e-6."""
    if len(bands) == 1:
        lo, hi = bands[0]
        # One band: exactly the draw the paper's sets were made with (their files must not change).
        return round(float(rng.uniform(lo, hi)), 6) if hi > lo else float(lo)
    widths = np.array([hi - lo for lo, hi in bands])
    # One uniform draw over the bands laid end to end = a band with probability proportional to
    # its width, then uniform inside it.
    u = float(rng.uniform(0.0, widths.sum()))
    k = min(int(np.searchsorted(np.cumsum(widths), u, side="right")), len(bands) - 1)
    lo, hi = bands[k]
    return round(min(lo + (u - float(widths[:k].sum())), hi), 6)


def random_team(rng: np.random.Generator, task: str, split: str, size: int) -> TeamSpec:
    """A team of ``size`` robots drawn like the set (task, split): >= 1 robot per type."""
    tt = TASK_TYPES[task]
    ranges = CAPABILITY_RANGES[(task, split)]
    # One robot of each type while there is room (the needed types come first in ``types``: a team
    # smaller than the type list lacks only optional types), the rest uniformly typed; shuffled order.
    first = list(tt.types[:size])
    if any(t not in first for t in tt.needed):
        raise ValueError(
            f"a {task} team needs at least {len(tt.needed)} robots (one of each of {tt.needed}), got {size}"
        )
    types = first + [tt.types[k] for k in rng.integers(0, len(tt.types), size - len(first))]
    rng.shuffle(types)
    robots = []
    for t in types:
        # Rounded to 1e-6 (what the YAML files hold), so files and generator agree exactly.
        robots.append(RobotSpec(t, tuple(_draw(rng, bands) for bands in ranges[t])))
    return TeamSpec(task, tuple(robots))


def _robots_key(team: TeamSpec) -> tuple:
    """The team as a multiset of robots: equal for the same robots in any order."""
    return tuple(sorted((r.type, r.capabilities) for r in team.robots))


def generate_coalitions(task: str, split: str, count: int = 20, seed: int = 0) -> list[TeamSpec]:
    """``count`` coalitions of the set (task, split), reproducible from ``seed`` (module docstring).

    Sizes are drawn from ``SIZES[split]``, except for ``size``, which cycles through its sizes
    (two teams of each of 2, 4, …, 20 for 20 coalitions) and lists the teams by size. ``val``
    redraws any team equal to one of the U_train set of the same seed and count.
    """
    if (task, split) not in CAPABILITY_RANGES:
        raise ValueError(f"(task, split) must be one of {sorted(CAPABILITY_RANGES)}, got {(task, split)!r}")
    if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or count < 1:
        raise ValueError(f"count must be a positive integer, got {count!r}")
    # One stream per (task, split), derived from the seed, so the sets do not depend on each other.
    rng = np.random.default_rng([seed, TASKS[task].streams[split]])
    if split == "size":
        sizes = sorted(SIZES[split][i % len(SIZES[split])] for i in range(count))
    else:
        sizes = rng.choice(SIZES[split], size=count)
    if split != "val":
        return [random_team(rng, task, split, int(n)) for n in sizes]
    seen = {_robots_key(t) for t in generate_coalitions(task, "train", count, seed)}
    teams = []
    for n in sizes:
        team = random_team(rng, task, split, int(n))
        while _robots_key(team) in seen:  # continuous capabilities: practically never
            team = random_team(rng, task, split, int(n))
        seen.add(_robots_key(team))
        teams.append(team)
    return teams


def save_coalitions(teams: Sequence[TeamSpec], path: str | Path, header: str = "") -> None:
    """Write coalitions as YAML (atomically)."""
    import yaml

    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    body = {"coalitions": [t.to_dict() for t in teams]}
    text = (f"# {header}\n" if header else "") + yaml.safe_dump(body, sort_keys=False, default_flow_style=None)
    tmp = p.with_suffix(p.suffix + ".tmp")
    tmp.write_text(text)
    tmp.replace(p)


def load_coalitions(path: str | Path, task: str | None = None) -> list[TeamSpec]:
    """Read a coalition file written by :func:`save_coalitions` (every team is validated); a file
    holding one team ``{'robots': [...]}`` is a set of one. ``task`` fills a team that names none."""
    import yaml

    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(f"coalition file {p} does not exist (regenerate with `comat coalitions`)")
    try:
        data = yaml.safe_load(p.read_bytes().decode("utf-8"))
    except (UnicodeDecodeError, yaml.YAMLError) as err:
        raise ValueError(f"{p}: expected a JSON/YAML file, got one that is not ({type(err).__name__})") from None
    if isinstance(data, dict) and "robots" in data and "coalitions" not in data:
        data = {"coalitions": [data]}
    if not isinstance(data, dict) or not isinstance(data.get("coalitions"), list):
        raise ValueError(  # noqa: TRY004 - bad file content
            f"{p}: expected a mapping with a 'coalitions' list or one team {{'robots': [...]}}, got {data!r:.80}"
        )
    return [TeamSpec.from_dict({"task": task or "", **t} if isinstance(t, dict) else t) for t in data["coalitions"]]


def load_team(path: str | Path, task: str | None = None) -> TeamSpec:
    """One team from a JSON/YAML file ``{'robots': [...]}`` (or a coalition file of one team)."""
    teams = load_coalitions(path, task)
    if len(teams) != 1:
        raise ValueError(
            f"team file {str(path)!r} must hold one team, got a set of {len(teams)} (pass it as coalitions)"
        )
    return teams[0]
