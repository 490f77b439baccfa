"""The registered tasks: the one list of tasks that every command, composition set, benchmark,
sweep and export reads (issue 49: a task is one place).

Each :class:`TaskEntry` names a task, its PettingZoo env id, its numpy task logic
(:mod:`comat.task_logic`: reset, dynamics, rewards, progress, the scripted heuristic; shipped with
every export) and its robot types and capabilities (:data:`comat.team.TASK_TYPES`).
:func:`task_names` is the order commands list them in; :func:`task_entry` turns a name into its
entry with a one-line error for a name that is not registered.
"""

from __future__ import annotations

from dataclasses import dataclass

from comat.tasks.hmt import HMT
from comat.tasks.pcp import PCP
from comat.team import TASK_TYPES, TaskTypes

__all__ = ["TASKS", "TaskEntry", "register_task", "task_entry", "task_names"]


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


register_task(TaskEntry("pcp", "pcp_v0", "Predator Capture Prey", PCP, TASK_TYPES["pcp"]))
register_task(TaskEntry("hmt", "hmt_v0", "Heterogeneous Material Transport", HMT, TASK_TYPES["hmt"]))
