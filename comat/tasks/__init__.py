"""The tasks: one module per task (``pcp.py``, ``hmt.py``, ``forage.py``, ``navigation.py``,
``sensors.py``, ``arctic.py``, ``warehouse.py``) and the one list of registered tasks that every
command, composition set, benchmark, sweep and export reads.

A task's module holds everything that is its own, in numpy only (an export ships it): its spec
sheet (the module docstring), robot types and capabilities, reset, the dynamics of its objects,
observations, named reward terms, progress and done, the scripted reference policy, how it is
drawn (:class:`comat.task_logic.Marks`), what an export carries of a reset (``layout``) and its
composition sets: the physical limits of its capabilities and which a type needs or lacks
(``capability_limits``, ``required``, ``ignored``), the bands each set draws them from
(``capability_bands``) and the sets' random streams (``set_streams``). :func:`task_from_logic`
registers such a class; :mod:`comat.team` draws every task's sets from its entry here. The
environments, the six sets, evaluation, report, export, Rerun and video read the registered tasks
with no task-specific code.

Each :class:`TaskEntry` names a task, its PettingZoo env id, its logic class, its robot types
(:class:`TaskTypes`), the capability bands of each of the six sets and their random streams.
:func:`task_names` is the order commands list them in;
:func:`task_entry` turns a name into its entry with a one-line error for a name that is not
registered.
"""

from __future__ import annotations

import importlib
import os
from collections.abc import Mapping
from dataclasses import dataclass
from importlib.metadata import entry_points

from comat.task_logic import TaskLogic
from comat.tasks.arctic import ArcticTransport
from comat.tasks.forage import LevelForaging
from comat.tasks.hmt import HMT
from comat.tasks.navigation import Navigation
from comat.tasks.pcp import PCP
from comat.tasks.sensors import SensorNetwork
from comat.tasks.warehouse import Warehouse

__all__ = [
    "COALITION_SETS",
    "LADDER",
    "RUNG_ALIASES",
    "TASKS",
    "Band",
    "TaskEntry",
    "TaskTypes",
    "check_task",
    "env_id",
    "load_plugins",
    "plugin_error",
    "register_task",
    "task_entry",
    "task_from_logic",
    "task_names",
]

COALITION_SETS = ("train", "val", "test", "scale", "size", "capability")
"""The named composition sets, in the order commands list them (:mod:`comat.team`)."""

LADDER = ("heuristic", "type_only", "blind", "constant", "random")
"""Every task's reference ladder, most informed first (:mod:`comat.envs.heuristics` runs it): the
scripted planner (``heuristic``), the same planner knowing types but not capabilities
(``type_only``), the planner with neither (``blind``), the best constant action, random actions."""
RUNG_ALIASES = {"scripted": "heuristic"}
"""Other names of a rung (the ladder's word for the heuristic)."""

_BANDS_FROM = {"val": "train", "size": "train", "scale": "test"}
"""U_val and U_size draw from the training bands, U_scale from the test ones; a task states the
bands of train, test and capability."""

Band = tuple[float, float]
"""Inclusive (low, high) interval of capability values; (0, 0): the capability is not used."""


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
    optional: tuple[str, ...] = ()
    """Types a team may lack (Arctic's scout: a 2-robot team is one ice and one water robot); every
    other type needs at least one robot. Sets draw one robot of each type, in ``types`` order, while
    the team has room."""

    @property
    def needed(self) -> tuple[str, ...]:
        """The types every team must have."""
        return tuple(t for t in self.types if t not in self.optional)


PLUGIN_ENV = "COMAT_TASKS"
"""Environment variable naming tasks of one's own to register on import: ``module:Class`` entries,
comma-separated (the module on ``PYTHONPATH``). Installed packages declare theirs as entry points
of the group ``comat.tasks`` (``name = "module:Class"``)."""


@dataclass(frozen=True)
class TaskEntry:
    """What names a task: ``name`` ("pcp"), ``env_id`` ("pcp_v0"), ``title`` (for people),
    ``logic`` (the task-logic class; ``logic.name`` is ``name``) and ``types`` (its robot types and
    capability layout)."""

    name: str
    env_id: str
    title: str
    logic: type
    types: TaskTypes
    bands: Mapping[str, Mapping[str, tuple[tuple[Band, ...], ...]]]
    """set -> type -> per capability, the bands its values are drawn from (every set)."""
    streams: Mapping[str, int]
    """set -> the random stream its teams are drawn from (no two tasks' sets share one)."""


TASKS: dict[str, TaskEntry] = {}
"""name -> entry, in registration order."""


def check_hooks(logic: type) -> None:
    """ValueError naming the task, the class and the required hooks (:data:`comat.task_logic.REQUIRED_HOOKS`)
    that ``logic`` lacks, or saying it is not a TaskLogic class."""
    name = getattr(logic, "name", None)
    if not (isinstance(logic, type) and issubclass(logic, TaskLogic)):
        raise TypeError(f"task {name!r}: its logic must be a class built on comat.task_logic.TaskLogic, got {logic!r}")
    missing = logic.missing_hooks()
    if missing:
        raise ValueError(
            f"task {name!r}: class {logic.__name__} lacks the required hook(s) {', '.join(missing)} "
            "(comat.task_logic.REQUIRED_HOOKS; docs/write-a-task.md)"
        )


def register_task(entry: TaskEntry) -> TaskEntry:
    """Add ``entry``; a logic class that lacks a required hook (:func:`check_hooks`), a name or env id
    that is taken, or a logic class of another name, is refused."""
    check_hooks(entry.logic)
    if entry.name in TASKS or any(e.env_id == entry.env_id for e in TASKS.values()):
        raise ValueError(f"task {entry.name!r} ({entry.env_id}) is registered already")
    if getattr(entry.logic, "name", None) != entry.name:
        raise ValueError(f"task {entry.name!r}: its logic class {entry.logic.__name__} is named {entry.logic.name!r}")
    taken = {stream: other.name for other in TASKS.values() for stream in other.streams.values()}
    clash = sorted(s for s in entry.streams.values() if s in taken)
    if clash:
        raise ValueError(
            f"task {entry.name!r}: set_streams reuses random streams {clash} "
            f"of task(s) {sorted({taken[s] for s in clash})}"
        )
    TASKS[entry.name] = entry
    return entry


def task_names() -> tuple[str, ...]:
    """The registered tasks' names, in the order commands list them."""
    return tuple(TASKS)


def task_entry(name: str) -> TaskEntry:
    """The entry of task ``name``; ValueError naming the registered ones otherwise."""
    if name not in TASKS:
        raise ValueError(f"task must be one of {list(TASKS)}, got {name!r}{_plugin_hint()}")
    return TASKS[name]


def env_id(name: str) -> str:
    """The env id of task ``name`` (``"pcp"`` -> ``"pcp_v0"``): a task whose rules changed has a newer
    version, so a policy or result of the old rules is never read against the new ones."""
    return task_entry(name).env_id


def task_from_logic(logic: type, title: str) -> TaskEntry:
    """Register the task whose logic class states its composition sets (module docstring): its env
    id is ``<name>_v<version>`` (the class's ``version``: 0 until a rule changes). ``set_streams``
    is the first of six consecutive streams (in :data:`COALITION_SETS` order) or a mapping set ->
    stream. A class that lacks a required hook is refused (:func:`check_hooks`)."""
    return register_task(entry_of(logic, title))


def entry_of(logic: type, title: str) -> TaskEntry:
    """The entry :func:`task_from_logic` registers for ``logic``, checked but not registered."""
    check_hooks(logic)
    name = logic.name
    types = TaskTypes(
        tuple(logic.types),
        tuple(logic.capabilities),
        tuple(tuple(lim) for lim in logic.capability_limits),
        tuple(tuple(r) for r in logic.required),
        tuple(tuple(i) for i in getattr(logic, "ignored", ())),
        tuple(getattr(logic, "optional_types", ())),
    )
    late = [t for t in types.optional if t in types.types and types.types.index(t) < len(types.needed)]
    if any(t not in types.types for t in types.optional) or late:
        raise ValueError(
            f"task {name!r}: optional_types must be types listed after every needed one in {types.types}, "
            f"got {types.optional}"
        )
    stated = logic.capability_bands
    missing = sorted({"train", "test", "capability"} - set(stated))
    if missing:
        raise ValueError(
            f"task {name!r}: capability_bands must name the sets train, test, capability; missing {missing}"
        )
    for split in ("train", "test", "capability"):
        if set(stated[split]) != set(types.types):
            raise ValueError(
                f"task {name!r}: capability_bands[{split!r}] must give every type {types.types}, "
                f"got {sorted(stated[split])}"
            )
    bands = {
        split: {
            t: tuple(tuple(tuple(b) for b in caps) for caps in per_type)
            for t, per_type in stated[_BANDS_FROM.get(split, split)].items()
        }
        for split in COALITION_SETS
    }
    first = logic.set_streams
    streams = (
        dict(first) if isinstance(first, Mapping) else {split: first + i for i, split in enumerate(COALITION_SETS)}
    )
    if set(streams) != set(COALITION_SETS):
        raise ValueError(
            f"task {name!r}: set_streams must give every set {list(COALITION_SETS)}, got {sorted(streams)}"
        )
    version = int(getattr(logic, "version", 0))
    return TaskEntry(name, f"{name}_v{version}", title, logic, types, bands, streams)


task_from_logic(PCP, "Predator Capture Prey")
task_from_logic(HMT, "Heterogeneous Material Transport")
task_from_logic(LevelForaging, "Level-Based Foraging")
task_from_logic(Navigation, "Navigation")
task_from_logic(SensorNetwork, SensorNetwork.title)
task_from_logic(ArcticTransport, ArcticTransport.title)
task_from_logic(Warehouse, Warehouse.title)


def load_plugins(spec: str | None = None) -> list[str]:
    """Register the tasks named by ``spec`` (default: the :data:`PLUGIN_ENV` variable) and by the
    ``comat.tasks`` entry points: each a task-logic class that states its composition sets (see
    :func:`task_from_logic`; its title is its ``title`` attribute or its class name). Returns the
    names registered; after registering every entry that loads, one ValueError line names each
    entry that did not, and why."""
    spec = os.environ.get(PLUGIN_ENV, "") if spec is None else spec
    found = [(f"{PLUGIN_ENV} entry {s.strip()!r}", s.strip(), None) for s in spec.split(",") if s.strip()]
    found += [
        (f"entry point {ep.name!r} = {ep.value!r} (group comat.tasks)", ep.value, ep)
        for ep in entry_points(group="comat.tasks")
    ]
    names, failed = [], []
    for where, target, ep in found:
        try:
            cls = _plugin_class(target, ep)
            if getattr(cls, "name", "") in TASKS and TASKS[cls.name].logic is cls:
                continue
            task_from_logic(cls, getattr(cls, "title", "") or cls.__name__)
        except (ValueError, TypeError) as err:
            failed.append(f"{where}: {err}")
            continue
        names.append(cls.name)
    if failed:
        raise ValueError("; ".join(failed))
    return names


def _plugin_class(target: str, ep) -> type:
    """The class a ``module:Class`` entry (or entry point ``ep``) names; ValueError (one line) saying
    why not: the module would not import (and what it raised) or lacks the class."""
    module, _, attr = target.partition(":")
    if not module or not attr:
        raise ValueError("expected module:Class")
    try:
        found = importlib.import_module(module)
    except Exception as err:  # whatever the module raises, said in one line
        why = err.msg if isinstance(err, ModuleNotFoundError) and err.name == module else f"{type(err).__name__}: {err}"
        raise ValueError(f"module {module!r} did not import ({' '.join(str(why).split())})") from err
    try:
        return ep.load() if ep is not None else getattr(found, attr)
    except AttributeError as err:
        raise ValueError(f"module {module!r} has no {attr!r}") from err


def plugin_error() -> str | None:
    """Why a plug-in task named by :data:`PLUGIN_ENV` or an entry point did not register when this
    module was imported (one line; None: every one did). Commands print it and stop (exit 2); a
    name asked for that is not registered is told it."""
    return _PLUGIN_ERROR


def _plugin_hint() -> str:
    return f" ({_PLUGIN_ERROR})" if _PLUGIN_ERROR else ""


def not_registered(name: str) -> str:
    """What to say of a task ``name`` that is not registered here (a run or file of a plug-in task
    read without it): how to register it."""
    return (
        f"task {name!r} is not registered here (registered: {', '.join(TASKS)}): register its task class "
        f"with {PLUGIN_ENV}=module:Class (the module on PYTHONPATH) or a comat.tasks entry point, as "
        f"when it was trained (docs/write-a-task.md){_plugin_hint()}"
    )


from comat.tasks.contract import check_task  # it builds on the registration above

try:  # a bad plug-in entry must not stop `import comat.tasks`: it is said where a task is asked for
    load_plugins()
    _PLUGIN_ERROR: str | None = None
except ValueError as _err:
    _PLUGIN_ERROR = str(_err)
