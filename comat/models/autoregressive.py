"""Sequential decision making shared by COMAT and MAT: encode once, then decode robot by robot.

Robot m's action distribution depends on the encoder output of robots 0..m and on the actions
of robots 0..m−1. ``act`` samples robot by robot with cached keys/values (one decoder step per
robot, no re-run of the prefix); ``evaluate_actions`` scores given actions in one teacher-forced
pass; ``act_uncached`` re-runs the whole decoder per robot (the slow reference for tests). The
three agree on log-probabilities. Action tokens: index 0 = start, index a+1 = action a.
Padded robots (mask False) sit at the end of the sequence, take action 0 and get log-prob 0.
"""

from __future__ import annotations

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from comat import kernels
from comat.models.layers import log_softmax_last, score_actions

__all__ = ["N_ACTIONS", "SIZE_BUCKET_COSTS", "AutoregressivePolicy", "numpy_view", "size_buckets"]

N_ACTIONS = 5


def numpy_view(t: torch.Tensor) -> np.ndarray:
    """A tensor's data as C-contiguous numpy for the kernels: a view of a contiguous tensor (a
    parameter), else a copy."""
    return t.detach().numpy() if t.is_contiguous() else t.detach().contiguous().numpy()


SIZE_BUCKET_COSTS = (1.0, 9.0, 7000.0)
"""Relative costs of a scored batch (forward and backward): per edge (robot pair) of a padded team,
per robot slot, and per group (the calls' own cost); fitted to COMAT's update on a 2-core Xeon
(640 PCP teams of 3, 5 and 7 robots: 0.9 µs an edge, 7.9 µs a slot, 6.2 ms a group), when COMAT's
update still scored padded batches (it now packs them where its kernels apply). They decide only
how a padded batch is grouped (:func:`size_buckets`), never a result."""


def size_buckets(sizes: list[int], counts: list[int]) -> list[tuple[int, int]]:
    """Contiguous groups (smallest, largest) of the sorted team ``sizes`` (with ``counts`` teams
    each) that minimize the cost of scoring each group padded to its largest team
    (:data:`SIZE_BUCKET_COSTS`); exact dynamic programming over the few distinct sizes."""
    edge, slot, group = SIZE_BUCKET_COSTS
    m = len(sizes)
    best = [0.0] + [float("inf")] * m  # best[k]: the cost of the first k sizes
    cut = [0] * (m + 1)
    for k in range(1, m + 1):
        for first in range(k):  # sizes[first:k] in one group, padded to sizes[k - 1]
            width = max(sizes[k - 1], 1)
            cost = best[first] + group + sum(counts[first:k]) * (edge * width * width + slot * width)
            if cost < best[k]:
                best[k], cut[k] = cost, first
    out, k = [], m
    while k:
        out.append((sizes[cut[k]], sizes[k - 1]))
        k = cut[k]
    return out[::-1]


class AutoregressivePolicy(nn.Module):
    """Subclasses implement ``encode``, ``decode_all``, ``decode_init`` and ``decode_step``."""

    n_actions = N_ACTIONS

    def encode(self, obs: torch.Tensor, mask: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Robot representations (B, N, D) and values (B, N)."""
        raise NotImplementedError

    def decode_all(self, rep, tokens, obs, mask) -> torch.Tensor:
        """Teacher-forced logits (B, N, A) from tokens (B, N, A+1) (start, a_0, …, a_{N−2})."""
        raise NotImplementedError

    def decode_init(self, rep: torch.Tensor, obs: torch.Tensor):
        """Fresh per-sequence decoding state (caches, per-sequence tables) for representations
        (B, N, D) of observations (B, N, D_obs)."""
        raise NotImplementedError

    def decode_step(self, state, m: int, token: torch.Tensor) -> torch.Tensor:
        """Logits (B, A) of robot m, given the token index (B,) of robot m−1's action (0 = start)."""
        raise NotImplementedError

    # -- public interface ----------------------------------------------------------------------
    group_by_team_size = False
    """Score a batch (:meth:`evaluate_actions`, :meth:`values`) one team size at a time, each group
    cut to its own robots: the same numbers for every real robot (padded slots sit at the end, see
    the module docstring, and no real robot attends to one), and the work of a model whose cost
    grows with the square of the slots (COMAT's N × N edges) falls with the teams' sizes; a model
    whose cost does not pays the extra calls for nothing, so it is opt-in."""

    def _by_team_size(self, fn, mask: torch.Tensor, *tensors: torch.Tensor) -> tuple[torch.Tensor, ...]:
        """``fn(mask, *tensors)`` -> tensors (B, N, ...) over the batch, evaluated per group of team
        sizes (:func:`size_buckets`) on the slots of the group's largest team only
        (:attr:`group_by_team_size`); padded slots come back 0. One call when grouping gains
        nothing or the mask is not a prefix."""
        B, N = mask.shape
        n = mask.sum(1)
        sizes, counts = torch.unique(n, return_counts=True)
        prefix = bool((mask == (torch.arange(N, device=mask.device)[None] < n[:, None])).all())
        buckets = size_buckets(sizes.tolist(), counts.tolist()) if self.group_by_team_size and prefix else []
        if len(buckets) < 2 and (not buckets or buckets[0][1] == N):
            return fn(mask, *tensors)
        outs, order = [], []
        for lo, hi in buckets:
            rows = torch.nonzero((n >= lo) & (n <= hi))[:, 0]
            order.append(rows)
            width = max(hi, 1)  # a group of empty teams still gets one (padded) slot
            part = fn(mask[rows, :width], *(t[rows, :width] for t in tensors))
            outs.append(tuple(F.pad(o, (0, 0) * (o.dim() - 2) + (0, N - width)) for o in part))
        inverse = torch.empty(B, dtype=torch.long, device=mask.device)
        inverse[torch.cat(order)] = torch.arange(B, device=mask.device)
        return tuple(torch.cat([o[k] for o in outs])[inverse] for k in range(len(outs[0])))

    def values(self, obs: torch.Tensor, mask: torch.Tensor, state: torch.Tensor | None = None) -> torch.Tensor:
        return self._by_team_size(lambda m, o: (self.encode(o, m)[1],), mask, obs)[0]

    def _token(self, actions: torch.Tensor) -> torch.Tensor:
        return F.one_hot(actions + 1, self.n_actions + 1).to(torch.get_default_dtype())

    def _start(self, batch: int, device) -> torch.Tensor:
        t = torch.zeros(batch, 1, self.n_actions + 1, device=device)
        t[..., 0] = 1.0
        return t

    @staticmethod
    def _choose(logits: torch.Tensor, deterministic: bool, generator: torch.Generator | None) -> torch.Tensor:
        if deterministic:
            return logits.argmax(-1)
        # Gumbel-max: an exact sample of softmax(logits), cheaper than multinomial here.
        u = torch.rand(logits.shape, generator=generator, device=logits.device).clamp_(1e-20, 1.0)
        return (logits - torch.log(-torch.log(u))).argmax(-1)

    def act(self, obs, mask, state=None, deterministic: bool = False, generator: torch.Generator | None = None):
        """Sample actions robot by robot (cached decoding).

        Returns actions (B, N) long, log-probs (B, N), values (B, N); padded slots 0.
        """
        B, N, _ = obs.shape
        compiled = self._compiled_ok(obs)
        rep, values = self.encode_compiled(obs, mask) if compiled else self.encode(obs, mask)
        noise = None
        if not deterministic:
            # Every robot's Gumbel noise in one draw: the same stream as one draw per robot.
            u = torch.rand((N, B, self.n_actions), generator=generator, device=obs.device).clamp_(1e-20, 1.0)
            noise = -torch.log(-torch.log(u))
        if compiled:
            actions_t, logits_t = self.decode_compiled(rep, obs, mask, noise)
        else:
            actions_t, logits_t = self._decode_loop(rep, obs, mask, noise)
        logp = log_softmax_last(logits_t).gather(-1, actions_t[..., None])[..., 0]
        return actions_t, logp * mask, values * mask

    def _decode_loop(self, rep, obs, mask, noise):
        """Cached decoding step by step in torch (the reference of :meth:`decode_compiled`):
        actions (B, N) and logits (B, N, A); argmax of logits (+ Gumbel noise (N, B, A))."""
        dec = self.decode_init(rep, obs)
        token = torch.zeros(rep.shape[0], dtype=torch.long, device=obs.device)  # the start token
        actions, logits = [], []
        for m in range(rep.shape[1]):
            logits_m = self.decode_step(dec, m, token)
            a = torch.where(mask[:, m], (logits_m if noise is None else logits_m + noise[m]).argmax(-1), 0)
            actions.append(a)
            logits.append(logits_m)
            token = a + 1
        return torch.stack(actions, 1), torch.stack(logits, 1)

    def decode_compiled(self, rep, obs, mask, noise):
        """:meth:`_decode_loop` in one compiled call (``comat.models.act_kernels``), for
        no-gradient CPU float32 calls; a model without one decodes with the loop."""
        raise NotImplementedError

    @staticmethod
    def _compiled_inputs(noise, mask):
        """Noise (N, B, A) (zeros when deterministic) and mask (B, N) as numpy for the kernels."""
        B, N = mask.shape
        noise_np = np.zeros((N, B, N_ACTIONS), np.float32) if noise is None else noise.contiguous().numpy()
        return noise_np, mask.contiguous().numpy()

    def encode_compiled(self, obs, mask):
        """:meth:`encode` for :meth:`act` when it decodes compiled: a model with a compiled
        encoder overrides this (COMAT); the others encode in torch."""
        return self.encode(obs, mask)

    def _compiled_ok(self, obs: torch.Tensor) -> bool:
        return (
            type(self).decode_compiled is not AutoregressivePolicy.decode_compiled
            and kernels.enabled()
            and not torch.is_grad_enabled()
            and obs.device.type == "cpu"
            and obs.dtype == torch.float32
            and next(self.parameters()).dtype == torch.float32
        )

    def act_uncached(self, obs, mask, deterministic: bool = True, generator: torch.Generator | None = None):
        """Reference: the whole decoder re-run on the prefix for every robot (slow)."""
        B, N, _ = obs.shape
        rep, values = self.encode(obs, mask)
        actions = torch.zeros(B, N, dtype=torch.long, device=obs.device)
        logps = torch.zeros(B, N, device=obs.device)
        for m in range(N):
            tokens = torch.cat([self._start(B, obs.device), self._token(actions[:, :-1])], 1)
            logits = self.decode_all(rep, tokens, obs, mask)[:, m]
            a = torch.where(mask[:, m], self._choose(logits, deterministic, generator), 0)
            actions[:, m] = a
            logps[:, m] = log_softmax_last(logits).gather(-1, a[:, None])[:, 0] * mask[:, m]
        return actions, logps, values * mask

    def evaluate_actions(self, obs, mask, actions, state=None):
        """Log-probs (B, N), entropies (B, N) and values (B, N) of given actions, one pass (one per
        team size with :attr:`group_by_team_size`)."""
        return self._by_team_size(lambda m, o, a: self._evaluate_actions(o, m, a), mask, obs, actions)

    def _evaluate_actions(self, obs, mask, actions):
        B = obs.shape[0]
        rep, values = self.encode(obs, mask)
        tokens = torch.cat([self._start(B, obs.device), self._token(actions[:, :-1])], 1)
        logp, entropy = score_actions(self.decode_all(rep, tokens, obs, mask), actions, mask)
        return logp, entropy, values * mask
