"""Robotarium tasks as PettingZoo parallel environments (``pcp_v0``, ``hmt_v0``) and a vector env."""

from comat.envs.base import TaskEnv
from comat.envs.hmt import HmtEnv
from comat.envs.pcp import PcpEnv

__all__ = ["HmtEnv", "PcpEnv", "TaskEnv"]
