"""Sequential decision making shared by COMAT and MAT: encode once, then decode robot by robot.

Robot m's action distribution depends on the encoder output of robots 0..m and on the actions
of robots 0..m−1. ``act`` samples robot by robot with cached keys/values (one decoder step per
robot, no re-run of the prefix); ``evaluate_actions`` scores given actions in one teacher-forced
pass; ``act_uncached`` re-runs the whole decoder per robot (the slow reference for tests). The
three agree on log-probabilities. Action tokens: index 0 = start, index a+1 = action a.
Padded robots (mask False) sit at the end of the sequence, take action 0 and get log-prob 0.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn

__all__ = ["N_ACTIONS", "AutoregressivePolicy"]

N_ACTIONS = 5


class AutoregressivePolicy(nn.Module):
    """Subclasses implement ``encode``, ``decode_all``, ``decode_init`` and ``decode_step``."""

    n_actions = N_ACTIONS

    def encode(self, obs: torch.Tensor, mask: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Robot representations (B, N, D) and values (B, N)."""
        raise NotImplementedError

    def decode_all(self, rep, tokens, obs, mask) -> torch.Tensor:
        """Teacher-forced logits (B, N, A) from tokens (B, N, A+1) (start, a_0, …, a_{N−2})."""
        raise NotImplementedError

    def decode_init(self, rep: torch.Tensor):
        """Fresh per-sequence decoding state (caches) for representations (B, N, D)."""
        raise NotImplementedError

    def decode_step(self, state, rep_m, token_m, obs_m, m: int) -> torch.Tensor:
        """Logits (B, A) of robot m, from its representation (B, 1, D) and token (B, 1, A+1)."""
        raise NotImplementedError

    # -- public interface ----------------------------------------------------------------------
    def values(self, obs: torch.Tensor, mask: torch.Tensor, state: torch.Tensor | None = None) -> torch.Tensor:
        return self.encode(obs, mask)[1]

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
        rep, values = self.encode(obs, mask)
        dec = self.decode_init(rep)
        token = self._start(B, obs.device)
        actions, logps = [], []
        for m in range(N):
            logits = self.decode_step(dec, rep[:, m : m + 1], token, obs[:, m : m + 1], m)
            a = torch.where(mask[:, m], self._choose(logits, deterministic, generator), 0)
            logps.append(torch.log_softmax(logits, -1).gather(-1, a[:, None])[:, 0] * mask[:, m])
            actions.append(a)
            token = self._token(a)[:, None]
        return torch.stack(actions, 1), torch.stack(logps, 1), values * mask

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
            logps[:, m] = torch.log_softmax(logits, -1).gather(-1, a[:, None])[:, 0] * mask[:, m]
        return actions, logps, values * mask

    def evaluate_actions(self, obs, mask, actions, state=None):
        """Log-probs (B, N), entropies (B, N) and values (B, N) of given actions, one pass."""
        B = obs.shape[0]
        rep, values = self.encode(obs, mask)
        tokens = torch.cat([self._start(B, obs.device), self._token(actions[:, :-1])], 1)
        logits = self.decode_all(rep, tokens, obs, mask)
        logp_all = torch.log_softmax(logits, -1)
        logp = logp_all.gather(-1, actions[..., None])[..., 0]
        entropy = -(logp_all.exp() * logp_all).sum(-1)
        return logp * mask, entropy * mask, values * mask
