"""Robotarium tasks as PettingZoo parallel environments (``pcp_v0``, ``hmt_v0`` and every task
:mod:`comat.tasks` registers) and a vector env.

``make_env(env_id, **options)`` and ``make_vec_env(env_id, num_envs, **options)`` check the
options and name any unknown one together with the valid ones; the options every env API shares
are the fields of :class:`EnvOptions`.
"""

from __future__ import annotations

from typing import Any

from comat.envs.base import TaskEnv
from comat.envs.options import EnvOptions
from comat.envs.registry import env_class, env_ids, make_env, make_local_vec_env
from comat.envs.sharded import ShardedVectorEnv
from comat.envs.vector import VectorEnv

__all__ = [
    "EnvOptions",
    "HmtEnv",
    "PcpEnv",
    "ShardedVectorEnv",
    "TaskEnv",
    "VectorEnv",
    "env_class",
    "env_ids",
    "make_env",
    "make_vec_env",
]

PcpEnv = env_class("pcp_v0")
HmtEnv = env_class("hmt_v0")


def make_vec_env(env_id: str, num_envs: int, workers: int = 1, **options: Any) -> VectorEnv | ShardedVectorEnv:
    """``num_envs`` environments of ``env_id``: one :class:`VectorEnv` in this process, or with
    ``workers`` > 1 a :class:`ShardedVectorEnv` over that many processes (options: see TaskEnv,
    plus ``seed``)."""
    if workers != 1:
        return ShardedVectorEnv(env_id, num_envs, workers=workers, **options)
    return make_local_vec_env(env_id, num_envs, **options)
