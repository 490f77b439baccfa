"""Scripted reference policies: show each task is solvable, and a reference row in evaluations.

They read the environment's full task state (prey positions, material left): *privileged*
information the learners do not get. Batched over B environments; padded slots get ``stay``.

* PCP: each sensing robot heads for the nearest prey nobody has sensed yet; each capture robot
  for the nearest sensed, uncaptured prey (else the nearest uncaptured one, to be close when it
  is sensed).
* HMT: a loaded robot heads for the drop-off; an empty one for its zone — fast robots prefer
  zone 2 (far, smaller) and slow robots zone 1 (near, larger) while both have material.
"""

from __future__ import annotations

import numpy as np

from comat.envs.core import TaskCore
from comat.task_logic import ZONE1_CENTRE, ZONE2_X

__all__ = ["heuristic_actions", "random_actions", "toward"]


def toward(points: np.ndarray, targets: np.ndarray, step: np.ndarray, has_target: np.ndarray) -> np.ndarray:
    """Actions (B, N) moving points (B, N, 2) toward targets along the larger axis; stay when
    within half a step on both axes or without a target."""
    d = targets - points
    ax = np.abs(d)
    along_x = ax[..., 0] >= ax[..., 1]
    act = np.where(along_x, np.where(d[..., 0] > 0, 1, 2), np.where(d[..., 1] > 0, 3, 4))
    close = np.maximum(ax[..., 0], ax[..., 1]) < 0.5 * step
    return np.where(has_target & ~close, act, 0)


def _nearest(points: np.ndarray, candidates: np.ndarray, allowed: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For points (B, N, 2), the nearest allowed candidate (B, K, 2) / allowed (B, N, K)."""
    d = candidates[:, None, :, :] - points[:, :, None, :]
    dist = np.where(allowed, d[..., 0] ** 2 + d[..., 1] ** 2, np.inf)
    k = np.argmin(dist, axis=-1)
    target = np.take_along_axis(candidates[:, None, :, :].repeat(points.shape[1], 1), k[..., None, None], 2)[..., 0, :]
    return target, np.isfinite(np.take_along_axis(dist, k[..., None], -1))[..., 0]


def _pcp(core: TaskCore, centres: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    st = core.state
    B, N = core.mask.shape
    K = st["prey"].shape[1]
    open_prey = ~st["captured"]
    sensing = (core.type_ids == 0)[..., None]
    to_sense = np.broadcast_to((~st["sensed"] & open_prey)[:, None, :], (B, N, K))
    to_capture = np.broadcast_to((st["sensed"] & open_prey)[:, None, :], (B, N, K))
    fallback = np.broadcast_to(open_prey[:, None, :], (B, N, K))
    t_sense, ok_sense = _nearest(centres, st["prey"], to_sense)
    t_capture, ok_capture = _nearest(centres, st["prey"], to_capture)
    t_any, ok_any = _nearest(centres, st["prey"], fallback)
    target = np.where(sensing, np.where(ok_sense[..., None], t_sense, t_any), np.where(ok_capture[..., None], t_capture, t_any))
    ok = np.where(sensing[..., 0], ok_sense | ok_any, ok_capture | ok_any)
    return target, ok


def _hmt(core: TaskCore, centres: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    st = core.state
    left = st["left"]  # (B, 2)
    loaded = st["load"] > 0
    y = np.clip(centres[..., 1], -0.8, 0.8)
    drop = np.stack([np.full_like(y, -ZONE2_X - 0.25), y], -1)
    zone1 = np.broadcast_to(np.array(ZONE1_CENTRE), centres.shape)
    zone2 = np.stack([np.full_like(y, ZONE2_X + 0.25), y], -1)
    has1, has2 = (left[:, 0] > 0)[:, None], (left[:, 1] > 0)[:, None]
    fast = core.type_ids == 0
    prefer2 = np.where(fast, has2, has2 & ~has1)
    empty_target = np.where((prefer2 | (has2 & ~has1))[..., None], zone2, zone1)
    target = np.where(loaded[..., None], drop, empty_target)
    ok = loaded | has1 | has2
    return target, ok


def heuristic_actions(core: TaskCore) -> np.ndarray:
    """Actions (B, N) of the scripted policy for every environment of ``core``."""
    centres = core.poses()[..., :2]
    target, ok = (_pcp if core.task.name == "pcp" else _hmt)(core, centres)
    step = core.task.step_lengths(core.caps)
    return np.where(core.mask, toward(centres, target, step, ok), 0)


def random_actions(rng: np.random.Generator, mask: np.ndarray) -> np.ndarray:
    """Uniformly random actions (B, N) for the real robots, stay for padded slots."""
    return np.where(mask, rng.integers(0, 5, mask.shape), 0)
