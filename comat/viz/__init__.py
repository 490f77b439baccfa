"""Rerun recordings of episodes: what the robots did and why (``comat rollout``).

* :class:`EpisodeRecorder` logs episodes of one environment into a ``rerun.RecordingStream``
  the caller owns; ``EpisodeRecorder(None)`` does nothing, so callers never branch on it.
* :func:`record_episodes` runs a policy (heuristic, random, checkpoint or callable) for some
  episodes and writes them to one ``.rrd`` file, one tab per episode (:func:`rollout_blueprint`).
* :func:`check_rrd_path` and :func:`resolve_policy` are the checks done before anything runs.
* :mod:`comat.envs.render` draws an episode top-down with matplotlib (``env.render()`` with
  ``render_mode="rgb_array"``); :mod:`comat.viz.video` encodes those frames to ``.mp4``/``.gif``
  (``comat rollout --video``).

Entity layout: :mod:`comat.viz.scene`. Open a file with ``rerun file.rrd``.

The names below load on first use: importing :mod:`comat.viz` does not import Rerun.
"""

from __future__ import annotations

import importlib
from typing import Any

__all__ = [
    "EpisodeRecorder",
    "RolloutResult",
    "check_rrd_path",
    "record_episodes",
    "record_training",
    "resolve_policy",
    "rollout_blueprint",
]

_HOME = {
    "EpisodeRecorder": "comat.viz.recorder",
    "RolloutResult": "comat.viz.rollout",
    "check_rrd_path": "comat.viz.rollout",
    "record_episodes": "comat.viz.rollout",
    "record_training": "comat.viz.rollout",
    "resolve_policy": "comat.viz.rollout",
    "rollout_blueprint": "comat.viz.blueprint",
}


def __getattr__(name: str) -> Any:
    if name not in _HOME:
        raise AttributeError(f"module 'comat.viz' has no attribute {name!r}")
    return getattr(importlib.import_module(_HOME[name]), name)


def __dir__() -> list[str]:
    return sorted(__all__)
