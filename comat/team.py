"""Team compositions: robots with a type and a capability vector, teams, and the paper's sets.

A task declares its robot types and capability names (:data:`TASK_TYPES`); a robot is a
``RobotSpec(type, capabilities)``; a team is a ``TeamSpec(task, robots)`` with at least one
robot of each type. The paper's composition sets (§III-D) are generated from a seed by
:func:`generate_coalitions` — the envs use that function, so the code is the source of these sets —
and stored as YAML in :data:`COALITIONS_DIR` (inside the package, linked from the checkout as
``train/coalitions/``; ``comat coalitions`` regenerates them, a test checks they match):

* U_train: 20 coalitions per task, team sizes drawn from {3, 5, 7};
* U_test: 20 coalitions per task, team sizes drawn from {2, 4, 6, 8};
* PCP (sensing radius, capture radius), m: train sensing U(0.3, 0.55), capture U(0.35, 0.45);
  test sensing U(0.2, 0.4), capture U(0.25, 0.4). A sensing robot's capture radius is 0 and a
  capture robot's sensing radius is 0.
* HMT (speed = waypoint step per env step, m; payload, units): train fast U(0.19, 0.45) /
  U(5, 12), slow U(0.10, 0.15) / U(16, 22); test fast U(0.15, 0.35) / U(7, 15), slow
  U(0.08, 0.18) / U(13, 28).
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
    "SIZES",
    "TASK_TYPES",
    "RobotSpec",
    "TaskTypes",
    "TeamSpec",
    "generate_coalitions",
    "load_coalitions",
    "random_team",
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
    "pcp": TaskTypes(("sensing", "capture"), ("sensing_radius_m", "capture_radius_m"), ((0.0, 1.0), (0.0, 1.0)), ((0,), (1,)),
                     ((1,), (0,))),
    # Step lengths are limited by 0.2 m/s over one 74-tick step (2.44 s): 0.488 m.
    "hmt": TaskTypes(("fast", "slow"), ("speed_m", "payload"), ((0.0, 0.488), (0.0, 100.0)), ((0, 1), (0, 1))),
}

SIZES = {"train": (3, 5, 7), "test": (2, 4, 6, 8), "scale": (10, 12, 16, 20)}
"""Team sizes of each composition set. U_scale goes past the 8 slots of the paper's baselines up to the
Robotarium's 20 robots, with U_test's capability ranges: the sizes where fixed-slot methods stop."""

COALITION_SETS = ("train", "test", "scale")
"""The named composition sets, in the order commands list them: U_train, U_test, U_scale."""

CAPABILITY_RANGES: dict[tuple[str, str], dict[str, tuple[tuple[float, float], ...]]] = {
    ("pcp", "train"): {"sensing": ((0.30, 0.55), (0.0, 0.0)), "capture": ((0.0, 0.0), (0.35, 0.45))},
    ("pcp", "test"): {"sensing": ((0.20, 0.40), (0.0, 0.0)), "capture": ((0.0, 0.0), (0.25, 0.40))},
    ("hmt", "train"): {"fast": ((0.19, 0.45), (5.0, 12.0)), "slow": ((0.10, 0.15), (16.0, 22.0))},
    ("hmt", "test"): {"fast": ((0.15, 0.35), (7.0, 15.0)), "slow": ((0.08, 0.18), (13.0, 28.0))},
}
"""(task, split) -> type -> per-capability uniform (low, high) ranges, from the paper §III-D."""
# U_scale changes only the team sizes: the unseen capability ranges are U_test's.
CAPABILITY_RANGES[("pcp", "scale")] = CAPABILITY_RANGES[("pcp", "test")]
CAPABILITY_RANGES[("hmt", "scale")] = CAPABILITY_RANGES[("hmt", "test")]

# Random stream of each set. Fixed numbers, not positions in a sorted list, so that adding a set
# never changes the teams of another (the first four are the sets' original sorted positions).
_STREAMS = {("hmt", "test"): 0, ("hmt", "train"): 1, ("pcp", "test"): 2, ("pcp", "train"): 3,
            ("hmt", "scale"): 4, ("pcp", "scale"): 5}


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
            for k in (tt.ignored[tt.types.index(r.type)] if tt.ignored else ()):
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


def random_team(rng: np.random.Generator, task: str, split: str, size: int) -> TeamSpec:
    """A team of ``size`` robots drawn like the paper's set (task, split): >= 1 robot per type."""
    tt = TASK_TYPES[task]
    ranges = CAPABILITY_RANGES[(task, split)]
    # At least one robot of each type, the rest uniformly typed; shuffled robot order.
    types = list(tt.types) + [tt.types[k] for k in rng.integers(0, len(tt.types), size - len(tt.types))]
    rng.shuffle(types)
    robots = []
    for t in types:
        # Rounded to 1e-6 (what the YAML files hold), so files and generator agree exactly.
        caps = tuple(round(float(rng.uniform(lo, hi)), 6) if hi > lo else float(lo) for lo, hi in ranges[t])
        robots.append(RobotSpec(t, caps))
    return TeamSpec(task, tuple(robots))


def generate_coalitions(task: str, split: str, count: int = 20, seed: int = 0) -> list[TeamSpec]:
    """``count`` coalitions of the paper's set (task, split), reproducible from ``seed``."""
    if (task, split) not in CAPABILITY_RANGES:
        raise ValueError(f"(task, split) must be one of {sorted(CAPABILITY_RANGES)}, got {(task, split)!r}")
    # One stream per (task, split), derived from the seed, so the sets do not depend on each other.
    rng = np.random.default_rng([seed, _STREAMS[(task, split)]])
    sizes = rng.choice(SIZES[split], size=count)
    return [random_team(rng, task, split, int(n)) for n in sizes]


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


def load_coalitions(path: str | Path) -> list[TeamSpec]:
    """Read a coalition file written by :func:`save_coalitions` (every team is validated)."""
    import yaml

    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(f"coalition file {p} does not exist (regenerate with `comat coalitions`)")
    data = yaml.safe_load(p.read_text())
    if not isinstance(data, dict) or not isinstance(data.get("coalitions"), list):
        raise ValueError(f"{p}: expected a mapping with a 'coalitions' list")  # noqa: TRY004 - bad file content
    return [TeamSpec.from_dict(t) for t in data["coalitions"]]
