"""Team compositions: robots with a type and a capability vector, teams, and the composition sets.

A task declares its robot types and capability names (:data:`TASK_TYPES`); a robot is a
``RobotSpec(type, capabilities)``; a team is a ``TeamSpec(task, robots)`` with at least one
robot of each type. The composition sets are generated from a seed by
:func:`generate_coalitions` — the envs use that function, so the code is the source of these sets —
and stored as YAML in :data:`COALITIONS_DIR` (inside the package, linked from the checkout as
``train/coalitions/``; ``comat coalitions`` regenerates them, a test checks they match). Each set
holds 20 coalitions per task and draws from its own random stream, so adding a set changes no
other set's teams. The sets (:data:`COALITION_SETS`; report names in :data:`SET_LABELS`):

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

Capability ranges (uniform; :data:`CAPABILITY_RANGES`):

* PCP (sensing radius, capture radius), m: train sensing U(0.3, 0.55), capture U(0.35, 0.45);
  test (and scale) sensing U(0.2, 0.4), capture U(0.25, 0.4); capability sensing
  [0.18, 0.30) ∪ (0.55, 0.75], capture [0.22, 0.35) ∪ (0.45, 0.60]. A sensing robot's capture
  radius is 0 and a capture robot's sensing radius is 0.
* HMT (speed = waypoint step per env step, m; payload, units): train fast U(0.19, 0.45) /
  U(5, 12), slow U(0.10, 0.15) / U(16, 22); test (and scale) fast U(0.15, 0.35) / U(7, 15), slow
  U(0.08, 0.18) / U(13, 28); capability fast [0.12, 0.19) ∪ (0.45, 0.488] / [2, 5) ∪ (12, 16],
  slow [0.06, 0.10) ∪ (0.15, 0.19] / [10, 16) ∪ (22, 30]. The fast robots' upper speed band
  ends at the physical limit 0.488 m (0.2 m/s over one 2.44 s step).

Capabilities are rounded to 1e-6 (what the files hold); U_cap's bands stop one such step short of
the training range, so a rounded value never lands on its edge.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

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
    "register_sets",
    "save_coalitions",
]


@dataclass(frozen=True)
class TaskTypes:
    """Robot types and capability layout of a task, with physical limits per capability."""

    types: tuple[str, ...]
    capabilities: tuple[str, ...]
    limits: tuple[tuple[float, float], ...]
    """Inclusive (low, high) physical limits of each capability (across all types)."""
    required: tuple[tuple[int, ...], ...]
    """Per type, indices of the capabilities that must be > 0 for it (its role)."""
    ignored: tuple[tuple[int, ...], ...] = ()
    """Per type, indices of the capabilities the task's rules ignore for it: they must be 0, so
    a team file cannot suggest an ability the robot does not have."""


TASK_TYPES: dict[str, TaskTypes] = {
    # Radii beyond 1 m would see or reach most of the 3.2 x 2 m arena from anywhere.
    "pcp": TaskTypes(
        ("sensing", "capture"),
        ("sensing_radius_m", "capture_radius_m"),
        ((0.0, 1.0), (0.0, 1.0)),
        ((0,), (1,)),
        ((1,), (0,)),
    ),
    # Step lengths are limited by 0.2 m/s over one 74-tick step (2.44 s): 0.488 m.
    "hmt": TaskTypes(("fast", "slow"), ("speed_m", "payload"), ((0.0, 0.488), (0.0, 100.0)), ((0, 1), (0, 1))),
}

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

COALITION_SETS = ("train", "val", "test", "scale", "size", "capability")
"""The named composition sets, in the order commands list them (module docstring)."""

SET_LABELS = {
    "train": "U_train",
    "val": "U_val",
    "test": "U_test",
    "scale": "U_scale",
    "size": "U_size",
    "capability": "U_cap",
}
"""Report and display name of each set."""

Band = tuple[float, float]
"""Inclusive (low, high) interval of capability values; (0, 0): the capability is not used."""

_GRAIN = 1e-6
"""Capabilities are rounded to this (what the YAML files hold)."""


def _one(lo: float, hi: float) -> tuple[Band, ...]:
    return ((lo, hi),)


_NONE = _one(0.0, 0.0)


def _outside(train: tuple[Band, ...], low: float, high: float) -> tuple[Band, ...]:
    """Bands [low, train low) and (train high, high] around a one-band training range, each
    ending one rounding step short of it (so a rounded draw is never on the range's edge)."""
    ((lo, hi),) = train
    return ((low, round(lo - _GRAIN, 6)), (round(hi + _GRAIN, 6), high))


CAPABILITY_RANGES: dict[tuple[str, str], dict[str, tuple[tuple[Band, ...], ...]]] = {
    ("pcp", "train"): {"sensing": (_one(0.30, 0.55), _NONE), "capture": (_NONE, _one(0.35, 0.45))},
    ("pcp", "test"): {"sensing": (_one(0.20, 0.40), _NONE), "capture": (_NONE, _one(0.25, 0.40))},
    ("hmt", "train"): {"fast": (_one(0.19, 0.45), _one(5.0, 12.0)), "slow": (_one(0.10, 0.15), _one(16.0, 22.0))},
    ("hmt", "test"): {"fast": (_one(0.15, 0.35), _one(7.0, 15.0)), "slow": (_one(0.08, 0.18), _one(13.0, 28.0))},
}
"""(task, set) -> type -> per capability, the bands its values are drawn from: uniform over their
union (a band chosen with probability proportional to its width, then uniform inside it). One
band for every set but U_cap. Train and test are the paper's §III-D ranges."""
for _task in ("pcp", "hmt"):
    # U_val is drawn like U_train; U_size keeps the training ranges; U_scale U_test's unseen ones.
    CAPABILITY_RANGES[(_task, "val")] = CAPABILITY_RANGES[(_task, "train")]
    CAPABILITY_RANGES[(_task, "size")] = CAPABILITY_RANGES[(_task, "train")]
    CAPABILITY_RANGES[(_task, "scale")] = CAPABILITY_RANGES[(_task, "test")]
_PT, _HT = CAPABILITY_RANGES[("pcp", "train")], CAPABILITY_RANGES[("hmt", "train")]
# U_cap: below and above the training range on both sides; each band's far end chosen so the
# set stays physically sensible (radii of 0.18-0.75 m; the fast robots' top speed is the limit).
CAPABILITY_RANGES[("pcp", "capability")] = {
    "sensing": (_outside(_PT["sensing"][0], 0.18, 0.75), _NONE),
    "capture": (_NONE, _outside(_PT["capture"][1], 0.22, 0.60)),
}
CAPABILITY_RANGES[("hmt", "capability")] = {
    "fast": (_outside(_HT["fast"][0], 0.12, 0.488), _outside(_HT["fast"][1], 2.0, 16.0)),
    "slow": (_outside(_HT["slow"][0], 0.06, 0.19), _outside(_HT["slow"][1], 10.0, 30.0)),
}
del _task, _PT, _HT

# Random stream of each set. Fixed numbers, not positions in a sorted list, so that adding a set
# never changes the teams of another (the first four are the sets' original sorted positions).
_STREAMS = {
    ("hmt", "test"): 0,
    ("hmt", "train"): 1,
    ("pcp", "test"): 2,
    ("pcp", "train"): 3,
    ("hmt", "scale"): 4,
    ("pcp", "scale"): 5,
    ("hmt", "val"): 6,
    ("pcp", "val"): 7,
    ("hmt", "size"): 8,
    ("pcp", "size"): 9,
    ("hmt", "capability"): 10,
    ("pcp", "capability"): 11,
}


def register_sets(task: str, types: TaskTypes, bands: Mapping[str, Mapping], stream_base: int) -> None:
    """Enter a task's types and composition sets (:mod:`comat.tasks` calls it for a task that states
    them): ``bands`` maps "train", "test" and "capability" to type -> per capability its bands; U_val
    and U_size draw from the training bands, U_scale from the test ones, as for PCP and HMT. The
    sets draw from the random streams ``stream_base`` … ``stream_base + 5`` (in
    :data:`COALITION_SETS` order), which no other task's set may use."""
    if task in TASK_TYPES:
        raise ValueError(f"task {task!r} has its types registered already")
    missing = {"train", "test", "capability"} - set(bands)
    if missing:
        raise ValueError(
            f"task {task!r}: capability_bands must name the sets train, test, capability; missing {sorted(missing)}"
        )
    streams = {(task, s): stream_base + i for i, s in enumerate(COALITION_SETS)}
    taken = set(streams.values()) & set(_STREAMS.values())
    if taken:
        raise ValueError(
            f"task {task!r}: set_streams {stream_base} reuses random streams {sorted(taken)} of another task"
        )
    for name in ("train", "test", "capability"):
        if set(bands[name]) != set(types.types):
            raise ValueError(
                f"task {task!r}: capability_bands[{name!r}] must give every type {types.types}, "
                f"got {sorted(bands[name])}"
            )
    TASK_TYPES[task] = types
    for s in COALITION_SETS:
        source = {"val": "train", "size": "train", "scale": "test"}.get(s, s)
        CAPABILITY_RANGES[(task, s)] = {k: tuple(tuple(b) for b in v) for k, v in bands[source].items()}
    _STREAMS.update(streams)


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
            raise ValueError(f"a {self.task} team needs at least one robot of each type {tt.types}, got an empty team")
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
        missing = [t for t in tt.types if all(r.type != t for r in self.robots)]
        if missing:
            raise ValueError(f"a {self.task} team needs at least one robot of each type {tt.types}; missing {missing}")

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
    # At least one robot of each type, the rest uniformly typed; shuffled robot order.
    types = list(tt.types) + [tt.types[k] for k in rng.integers(0, len(tt.types), size - len(tt.types))]
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
    rng = np.random.default_rng([seed, _STREAMS[(task, split)]])
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
