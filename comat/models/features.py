"""What the models read: padded observations and a mask, decoded into types, capabilities, graphs.

Every model takes ``obs`` (B, N, D) and ``mask`` (B, N) (True for real robots, padded slots at
the end). The task's observation layout (``comat/task_logic.py``) starts with
[x, y, cos θ, sin θ | type one-hot (T) | capabilities (C) | task features], so the team graph
(relative positions, distances, relative headings, ordered type pairs) is rebuilt from the
observations themselves — ``env.graph()`` plus self-loops — and no input depends on N.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from numba import njit

from comat.models.packing import PackedTeams

__all__ = ["ObsLayout", "edge_features", "packed_edge_features"]


@dataclass(frozen=True)
class ObsLayout:
    """Where things are in an observation vector.

    Attributes:
        obs_dim: D.
        n_types: T, robot types of the task.
        n_caps: C, capability dimensions.
    """

    obs_dim: int
    n_types: int
    n_caps: int

    def types(self, obs: torch.Tensor) -> torch.Tensor:
        """(B, N) type ids from the one-hot block."""
        return obs[..., 4 : 4 + self.n_types].argmax(-1)

    def capabilities(self, obs: torch.Tensor) -> torch.Tensor:
        """(B, N, C) scaled capability vectors."""
        return obs[..., 4 + self.n_types : 4 + self.n_types + self.n_caps]

    @classmethod
    def for_task(cls, task) -> ObsLayout:
        return cls(task.obs_size(), len(task.types), len(task.capabilities))


def edge_features(
    obs: torch.Tensor, mask: torch.Tensor, layout: ObsLayout, world: bool = False
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Dense team graph with self-loops, from observations.

    Returns:
        edge_attr (B, N, N, 5): for [b, i, j], robot j seen from robot i — position in i's
            frame (2; ``world``: p_j − p_i in the world frame), distance (1), relative heading
            cos, sin (2); (0, 0, 0, 1, 0) on the diagonal.
        edge_type (B, N, N): type_i · T + type_j.
        edge_mask (B, N, N): both robots real (self-loops included).
    """
    xy, c, s = obs[..., 0:2], obs[..., 2], obs[..., 3]
    d = xy[:, None, :, :] - xy[:, :, None, :]  # [b, i, j] = p_j - p_i
    not_self = 1 - torch.eye(obs.shape[1], device=obs.device)
    edge_attr = _seen_from(d, c[:, :, None], s[:, :, None], c[:, None, :], s[:, None, :], not_self, world)
    types = layout.types(obs)
    edge_type = types[:, :, None] * layout.n_types + types[:, None, :]
    edge_mask = mask[:, :, None] & mask[:, None, :]
    return edge_attr, edge_type, edge_mask


def packed_edge_features(
    obs: torch.Tensor, packed: PackedTeams, layout: ObsLayout, world: bool = False
) -> tuple[torch.Tensor, torch.Tensor]:
    """:func:`edge_features` of a packed batch (``comat.models.packing``): observations (R, D) ->
    edge_attr (M, 5) and edge_type (M,), edge m robot ``packed.edge_j[m]`` seen from robot
    ``packed.edge_i[m]``. One compiled pass over the edges (the observations carry no gradient) with
    the dense graph's float32 arithmetic in its order: the same bits, but for the distance, within
    one unit in the last place (torch's squares and numba's differ there)."""
    attr = torch.empty((packed.edge_i.shape[0], 5), dtype=obs.dtype)
    edge_type = torch.empty(packed.edge_i.shape[0], dtype=torch.long)
    types = packed.types.numpy()
    rows = obs.detach()[:, :4].contiguous().numpy()
    _seen_from_packed(rows, types, packed.size, packed.start, layout.n_types, world, attr.numpy(), edge_type.numpy())
    return attr, edge_type


@njit(cache=True, nogil=True)
def _seen_from_packed(rows, types, size, start, n_types, world, attr, edge_type):  # pragma: no cover - compiled
    """:func:`_seen_from` over a packed batch's edges, team by team, robot i then robot j; rows
    (R, 4) each robot's x, y, cos θ, sin θ."""
    eps = np.float32(1e-12)
    e = 0
    for b in range(size.shape[0]):
        s0 = start[b]
        for i in range(size[b]):
            xi, yi, ci, si = rows[s0 + i, 0], rows[s0 + i, 1], rows[s0 + i, 2], rows[s0 + i, 3]
            for j in range(size[b]):
                dx, dy = rows[s0 + j, 0] - xi, rows[s0 + j, 1] - yi
                cj, sj = rows[s0 + j, 2], rows[s0 + j, 3]
                if world:
                    attr[e, 0], attr[e, 1] = dx, dy
                else:
                    attr[e, 0] = ci * dx + si * dy
                    attr[e, 1] = -si * dx + ci * dy
                attr[e, 2] = np.sqrt(dx * dx + dy * dy + eps) * np.float32(i != j)
                attr[e, 3] = ci * cj + si * sj
                attr[e, 4] = ci * sj - si * cj
                edge_type[e] = types[s0 + i] * n_types + types[s0 + j]
                e += 1


def _seen_from(d, ci, si, cj, sj, not_self, world: bool) -> torch.Tensor:
    """Edge features (..., 5) of robot j seen from robot i, from p_j − p_i (..., 2), both headings'
    cosines and sines and 0 on self-loops (``not_self``), all broadcast to the edges' shape."""
    if world:
        local_x, local_y = d[..., 0], d[..., 1]
    else:
        local_x = ci * d[..., 0] + si * d[..., 1]
        local_y = -si * d[..., 0] + ci * d[..., 1]
    dist = torch.sqrt(d[..., 0] ** 2 + d[..., 1] ** 2 + 1e-12) * not_self
    rel_cos = ci * cj + si * sj  # cos(θ_j − θ_i)
    rel_sin = ci * sj - si * cj  # sin(θ_j − θ_i)
    return torch.stack([local_x, local_y, dist, rel_cos, rel_sin], dim=-1)
