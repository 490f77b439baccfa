"""The environments of the registered tasks (:mod:`comat.tasks`) and their options: ``env_id`` ->
env class, options checked by name.

Every registered task gets its PettingZoo env class here, made from its entry (no task has code of
its own in :mod:`comat.envs`): :func:`env_class`. :func:`comat.envs.make_env` and
:func:`comat.envs.make_vec_env` are the public faces; a sharded vector env's workers build their
share with :func:`make_local_vec_env`.
"""

from __future__ import annotations

import inspect
from typing import Any

from comat.envs.base import TaskEnv
from comat.envs.options import EnvOptions
from comat.envs.vector import VectorEnv
from comat.tasks import TASKS, TaskEntry, plugin_error

__all__ = ["check_options", "env_class", "env_ids", "make_env", "make_local_vec_env", "make_task"]

_CLASSES: dict[str, type[TaskEnv]] = {}


def env_ids() -> tuple[str, ...]:
    """The env ids of the registered tasks, sorted."""
    return tuple(sorted(e.env_id for e in TASKS.values()))


def _new_class(entry: TaskEntry) -> type[TaskEnv]:
    name = "".join(part.capitalize() for part in entry.name.split("_")) + "Env"
    cls = type(
        name,
        (TaskEnv,),
        {
            "__doc__": f"{entry.title} as a PettingZoo parallel env; spec sheet: :mod:`{entry.logic.__module__}`.",
            "__module__": __name__,
            "metadata": {"name": entry.env_id, "render_modes": ["rgb_array"], "is_parallelizable": True},
            "task_cls": entry.logic,
        },
    )
    globals()[name] = cls  # found by name, as pickle and copy look classes up
    return cls


def env_class(env_id: str) -> type[TaskEnv]:
    """The PettingZoo env class of a registered task's ``env_id`` (made once, on first use); a task's
    bare name (``"navigation"``) is its current env id."""
    if env_id in TASKS:
        env_id = TASKS[env_id].env_id
    if env_id not in _CLASSES:
        entry = next((e for e in TASKS.values() if e.env_id == env_id), None)
        if entry is None:
            now = TASKS.get(env_id.rsplit("_v", 1)[0]) if isinstance(env_id, str) else None
            hint = f" ({now.name}'s rules changed: it is {now.env_id} now)" if now is not None else ""
            broken = f" ({plugin_error()})" if plugin_error() else ""
            raise ValueError(f"env_id must be one of {env_ids()}, got {env_id!r}{hint}{broken}")
        _CLASSES[env_id] = _new_class(entry)
    return _CLASSES[env_id]


_env_class = env_class


def check_options(env_id: str, options: dict[str, Any], extra: tuple[str, ...] = (), vector: bool = False) -> None:
    """ValueError naming every option of ``options`` that ``env_id`` does not take, and the valid ones:
    the env options (:class:`EnvOptions`), the task's own, ``render_mode`` (PettingZoo env only) and
    ``extra``."""
    cls = _env_class(env_id)
    valid = set(EnvOptions.names())
    if not vector:  # a vector env draws nothing: render_mode belongs to the PettingZoo env alone
        valid.add("render_mode")
    valid |= {p for p in inspect.signature(cls.task_cls.__init__).parameters if p not in ("self", "args", "kwargs")}
    valid |= set(extra)
    unknown = sorted(set(options) - valid)
    if unknown:
        raise ValueError(f"unknown option(s) {unknown} for {env_id}; valid options: {sorted(valid)}")


def make_env(env_id: str, **options: Any) -> TaskEnv:
    """A PettingZoo parallel environment: ``"pcp_v0"``, ``"hmt_v0"``, … or a task's name for its current
    version (``"navigation"``; options: see TaskEnv)."""
    check_options(env_id, options)
    return _env_class(env_id)(**options)


def make_local_vec_env(env_id: str, num_envs: int, **options: Any) -> VectorEnv:
    """``num_envs`` environments of ``env_id`` in this process (options: see TaskEnv, plus ``seed``
    and ``shard``); what :func:`comat.envs.make_vec_env` builds with one worker, and each worker of a
    :class:`~comat.envs.sharded.ShardedVectorEnv`."""
    check_options(env_id, options, extra=("seed", "shard"), vector=True)
    task, rest = make_task(env_id, options)
    return VectorEnv(task, num_envs, **rest)


def make_task(env_id: str, options: dict[str, Any]):
    """The task-logic instance from the task's own options, and the remaining (env) options."""
    cls = _env_class(env_id)
    task_keys = set(inspect.signature(cls.task_cls.__init__).parameters) - {"self"}
    task = cls.task_cls(**{k: v for k, v in options.items() if k in task_keys})
    return task, {k: v for k, v in options.items() if k not in task_keys}
