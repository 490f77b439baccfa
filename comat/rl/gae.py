"""Generalized advantage estimation over a rollout, vectorized over environments.

Paper eq. 9: the joint advantage Â_t = Σ_l (γλ)^l δ_{t+l}, δ_t = R_t + γ·V̂_{t+1} − V̂_t, with
V̂ the mean of the robots' values. Autoreset is same-step, so ``next_values`` holds the value
of the state after step t *in the same episode*: the final observation's value where the
episode was truncated, 0 where it terminated. The recursion stops at every episode end.
"""

from __future__ import annotations

import torch

__all__ = ["gae", "standardize"]


def gae(
    rewards: torch.Tensor,
    values: torch.Tensor,
    next_values: torch.Tensor,
    dones: torch.Tensor,
    gamma: float,
    lam: float,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Advantages and returns, both (T, B) (or (T, B, N): every argument may carry trailing
    dimensions, e.g. one value per robot).

    Args:
        rewards: (T, B) team rewards.
        values: (T, B) V̂(o_t).
        next_values: (T, B) V̂ of the next state of the same episode (0 after termination).
        dones: (T, B) bool, the episode ended at step t (terminated or truncated).
    """
    T = rewards.shape[0]
    deltas = rewards + gamma * next_values - values
    carry = (gamma * lam) * (~dones).to(rewards.dtype)
    advantages = torch.empty_like(rewards)
    running = torch.zeros_like(rewards[0])
    for t in range(T - 1, -1, -1):
        running = deltas[t] + carry[t] * running
        advantages[t] = running
    return advantages, advantages + values


def standardize(adv: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """Advantages with mean 0 and std 1 over a rollout: a team's (T, B) over all its entries, the
    robots' own (T, B, N) over the real robots' entries (``mask`` (T, B, N); padded slots 0)."""
    if adv.dim() == mask.dim() - 1:
        return (adv - adv.mean()) / (adv.std() + 1e-8)
    real = adv[mask]
    return (adv - real.mean()) / (real.std() + 1e-8) * mask
