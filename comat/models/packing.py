"""A batch of teams packed as one graph: every team's real robots as the rows of one matrix, every
ordered pair of robots of a team (self-loops included) as a row of one edge list.

Why (issue 48): COMAT's update scored padded teams, (B, N) robot slots and (B, N, N) edges, in one
group of calls per band of team sizes. On a PCP minibatch (640 teams of 3, 5 and 7 robots in
slots of 7) a tenth of the slots and a sixth of the edges were padding, and the second band of
sizes a second pass of every call. Packed, a minibatch is one pass over its real robots and
real edges; the per-robot layers do not change (they act on rows), and the two stages that mix
a team's robots, the HEAT edge stage and the decoder's causal attention, run in compiled kernels
that read the team tables below (:mod:`comat.models.heat_kernels`,
:mod:`comat.models.attention_kernels`).

Shapes: B teams in N slots; R = Σ_b n_b real robots, team b's at rows start[b] … start[b]+n_b−1
in slot order; M = Σ_b n_b² edges, team b's edge (i, j) (robot j seen from robot i) at row
edge_start[b] + i·n_b + j.
"""

from __future__ import annotations

import itertools
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np
import torch
from numba import njit

__all__ = ["PackedTeams", "pack"]


@dataclass(frozen=True)
class PackedTeams:
    """Where each team's robots and edges sit in the packed rows (see the module docstring)."""

    slots: torch.Tensor
    """(R,) long: b·N + i, each real robot's slot in the flattened (B·N) batch."""
    first: torch.Tensor
    """(R,) bool: the robot is its team's first (it decodes after the start token)."""
    edge_i: torch.Tensor
    """(M,) long: the row of each edge's robot i (the one who sees)."""
    edge_j: torch.Tensor
    """(M,) long: the row of each edge's robot j (the one seen)."""
    size: np.ndarray
    """(B,) int64: n_b."""
    start: np.ndarray
    """(B,) int64: team b's first robot row."""
    edge_start: np.ndarray
    """(B,) int64: team b's first edge row."""
    types: torch.Tensor
    """(R,) long: each robot's type id."""
    by_type: tuple[torch.Tensor, ...]
    """Per robot type t, (R_t,) long: the rows of type t's robots, in order."""
    type_inverse: torch.Tensor
    """(R,) long: each row's place in the rows of ``by_type`` concatenated."""
    batch: int
    slots_per_team: int

    def gather(self, x: torch.Tensor) -> torch.Tensor:
        """(B, N, ...) -> (R, ...): the real robots' rows."""
        return x.reshape(self.batch * self.slots_per_team, *x.shape[2:]).index_select(0, self.slots)

    def scatter(self, x: torch.Tensor) -> torch.Tensor:
        """(R, ...) -> (B, N, ...): rows back in their slots, padded slots 0 (differentiable)."""
        out = x.new_zeros(self.batch * self.slots_per_team, *x.shape[1:]).index_copy(0, self.slots, x)
        return out.view(self.batch, self.slots_per_team, *x.shape[1:])


def pack(mask: torch.Tensor, types: torch.Tensor, n_types: int) -> PackedTeams | None:
    """The packing of a batch whose mask (B, N) holds each team's real robots first, their type ids
    ``types`` (B, N) in 0 … n_types − 1; None when a padded slot comes before a real one (such a
    batch is scored padded)."""
    B, N = mask.shape
    n = mask.sum(1)
    if not bool((mask == (torch.arange(N, device=mask.device)[None] < n[:, None])).all()):
        return None
    size = n.cpu().numpy().astype(np.int64)
    start, edge_start, *rows = _index(size, N)
    slots, first, edge_i, edge_j = (torch.from_numpy(a) for a in rows)
    row_types = types.reshape(-1)[slots]
    order = torch.argsort(row_types, stable=True)
    type_inverse = torch.empty_like(order)
    type_inverse[order] = torch.arange(order.shape[0])
    by_type = order.split(torch.bincount(row_types, minlength=n_types).tolist())
    return PackedTeams(slots, first, edge_i, edge_j, size, start, edge_start, row_types, by_type, type_inverse, B, N)


@njit(cache=True, nogil=True)
def _index(size, slots_per_team):  # pragma: no cover - compiled
    B = size.shape[0]
    R, M = 0, 0
    for b in range(B):
        R += size[b]
        M += size[b] * size[b]
    start, edge_start = np.empty(B, np.int64), np.empty(B, np.int64)
    slots, first = np.empty(R, np.int64), np.zeros(R, np.bool_)
    edge_i, edge_j = np.empty(M, np.int64), np.empty(M, np.int64)
    r, e = 0, 0
    for b in range(B):
        n = size[b]
        start[b], edge_start[b] = r, e
        if n:
            first[r] = True
        for i in range(n):
            slots[r + i] = b * slots_per_team + i
            for j in range(n):
                edge_i[e], edge_j[e] = r + i, r + j
                e += 1
        r += n
    return start, edge_start, slots, first, edge_i, edge_j


_helper: ThreadPoolExecutor | None = None


def split_teams(size: np.ndarray, parts: int) -> list[slice]:
    """``parts`` contiguous slices of the teams (sizes ``size`` (B,)) with about equal numbers of
    edges, the kernels' work; fewer where there are fewer teams."""
    B = size.shape[0]
    if parts < 2 or B < 2:
        return [slice(0, B)]
    work = np.cumsum(size * size)
    cuts = np.searchsorted(work, [work[-1] * k / parts for k in range(1, parts)]) + 1
    bounds = [0, *sorted({int(c) for c in cuts if 0 < c < B}), B]
    return [slice(a, b) for a, b in itertools.pairwise(bounds)]


def parts() -> int:
    """How many parts a kernel's teams are split into: 2 where torch may use more than one thread."""
    return 2 if torch.get_num_threads() > 1 else 1


def on_threads(run, size: np.ndarray, n_parts: int) -> None:
    """``run(teams, part)`` for ``n_parts`` slices of the teams (sizes ``size``, :func:`split_teams`)
    at once, all but the first in a helper thread: the kernels release the GIL and write disjoint
    rows."""
    global _helper
    slices = split_teams(size, n_parts)
    if len(slices) == 1:
        run(slices[0], 0)
        return
    if _helper is None:
        _helper = ThreadPoolExecutor(1, thread_name_prefix="comat-kernels")
    jobs = [_helper.submit(run, teams, k) for k, teams in enumerate(slices[1:], 1)]
    run(slices[0], 0)
    for job in jobs:
        job.result()
