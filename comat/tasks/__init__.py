"""The tasks: one module per task (``pcp.py``, ``hmt.py``, ``forage.py``, ``navigation.py``,
``sensors.py``, ``arctic.py``) and the one list of registered tasks that every command, composition set,
benchmark, sweep and export reads.

A task's module holds everything that is its own, in numpy only (an export ships it): its spec
sheet (the module docstring), robot types and capabilities, reset, the dynamics of its objects,
observations, named reward terms, progress and done, the scripted reference policy, how it is
drawn (:class:`comat.task_logic.Marks`) and what an export carries of a reset (``layout``); a task
added after PCP and HMT also states its composition sets' capability bands
(``capability_bands``, ``capability_limits``, ``required``, ``set_streams``), which
:func:`register_task` enters in :mod:`comat.team`. The environments, the six sets, evaluation,
report, export, Rerun and video read the registered tasks with no task-specific code.

Each :class:`TaskEntry` names a task, its PettingZoo env id, its logic class and its robot types
(:data:`comat.team.TASK_TYPES`). :func:`task_names` is the order commands list them in;
:func:`task_entry` turns a name into its entry with a one-line error for a name that is not
registered.
"""

from __future__ import annotations

import importlib
import os
from dataclasses import dataclass
from importlib.metadata import entry_points

from comat.tasks.arctic import ArcticTransport
from comat.tasks.forage import LevelForaging
from comat.tasks.hmt import HMT
from comat.tasks.navigation import Navigation
from comat.tasks.pcp import PCP
from comat.tasks.sensors import SensorNetwork
from comat.team import TASK_TYPES, TaskTypes, register_sets

__all__ = ["TASKS", "TaskEntry", "load_plugins", "register_task", "task_entry", "task_from_logic", "task_names"]

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


TASKS: dict[str, TaskEntry] = {}
"""name -> entry, in registration order."""


def register_task(entry: TaskEntry) -> TaskEntry:
    """Add ``entry``; a name or env id that is taken, or a logic class of another name, is refused."""
    if entry.name in TASKS or any(e.env_id == entry.env_id for e in TASKS.values()):
        raise ValueError(f"task {entry.name!r} ({entry.env_id}) is registered already")
    if getattr(entry.logic, "name", None) != entry.name:
        raise ValueError(f"task {entry.name!r}: its logic class {entry.logic.__name__} is named {entry.logic.name!r}")
    TASKS[entry.name] = entry
    return entry


def task_names() -> tuple[str, ...]:
    """The registered tasks' names, in the order commands list them."""
    return tuple(TASKS)


def task_entry(name: str) -> TaskEntry:
    """The entry of task ``name``; ValueError naming the registered ones otherwise."""
    if name not in TASKS:
        raise ValueError(f"task must be one of {list(TASKS)}, got {name!r}")
    return TASKS[name]


def task_from_logic(logic: type, title: str) -> TaskEntry:
    """Register the task whose logic class states its composition sets (``capability_bands``,
    ``capability_limits``, ``required``, ``set_streams``): its types and sets enter
    :mod:`comat.team`, its env id is ``<name>_v0``."""
    types = TaskTypes(logic.types, logic.capabilities, logic.capability_limits, logic.required)
    register_sets(logic.name, types, logic.capability_bands, logic.set_streams)
    return register_task(TaskEntry(logic.name, f"{logic.name}_v0", title, logic, types))


register_task(TaskEntry("pcp", "pcp_v0", "Predator Capture Prey", PCP, TASK_TYPES["pcp"]))
register_task(TaskEntry("hmt", "hmt_v0", "Heterogeneous Material Transport", HMT, TASK_TYPES["hmt"]))
task_from_logic(LevelForaging, "Level-Based Foraging")
task_from_logic(Navigation, "Navigation")
task_from_logic(SensorNetwork, SensorNetwork.title)
task_from_logic(ArcticTransport, ArcticTransport.title)


def load_plugins(spec: str | None = None) -> list[str]:
    """Register the tasks named by ``spec`` (default: the :data:`PLUGIN_ENV` variable) and by the
    ``comat.tasks`` entry points: each a task-logic class that states its composition sets (see
    :func:`task_from_logic`; its title is its ``title`` attribute or its class name). Returns the
    names registered; a bad entry raises ValueError naming it."""
    spec = os.environ.get(PLUGIN_ENV, "") if spec is None else spec
    found = [(s.strip(), None) for s in spec.split(",") if s.strip()]
    found += [(ep.value, ep) for ep in entry_points(group="comat.tasks")]
    names = []
    for target, ep in found:
        try:
            if ep is not None:
                cls = ep.load()
            else:
                module, _, attr = target.partition(":")
                if not module or not attr:
                    raise ValueError("expected module:Class")
                cls = getattr(importlib.import_module(module), attr)
        except (ImportError, AttributeError, ValueError) as err:
            raise ValueError(f"{PLUGIN_ENV} / comat.tasks entry {target!r}: {err}") from err
        if getattr(cls, "name", "") in TASKS and TASKS[cls.name].logic is cls:
            continue
        task_from_logic(cls, getattr(cls, "title", "") or cls.__name__)
        names.append(cls.name)
    return names


load_plugins()
