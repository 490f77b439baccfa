"""Counter-based random numbers for the reality layer: a pure function of (robot key, tick, stream).

Each robot gets a 64-bit key per episode; a draw is SplitMix64 at position
``1024·tick + stream`` of the sequence that starts at the key (key + position·γ, then the
finalizer). So every robot's noise depends only on
its episode's seed and its own clock, never on the other teams in the batch or the order of
resets, and one numpy expression draws for all robots at once (no per-robot generator objects,
no Python loop per tick). The finalizer passes BigCrush as a generator of its counter; we use it
for noise in a simulator, not for cryptography.
"""

from __future__ import annotations

import copy

import numpy as np

from comat import kernels
from comat.reality import kernels as rk

__all__ = [
    "EPISODE",
    "NORMAL_BOUND",
    "bits",
    "episode_key",
    "normal_table",
    "normals",
    "robot_keys",
    "tick_draws",
    "to_normal",
    "to_uniform",
    "uniforms",
]

_M0 = np.uint64(0x9E3779B97F4A7C15)
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
_S30, _S27, _S31, _S11 = np.uint64(30), np.uint64(27), np.uint64(31), np.uint64(11)
_STREAMS_PER_TICK = 1024
_TICK_MUL = np.uint64((_STREAMS_PER_TICK * 0x9E3779B97F4A7C15) % 2**64)  # γ·1024, wrapped
_STREAM_MUL = np.uint64(0x8CB92BA72F3D8DD7)
_ROBOT_SALT = np.uint64(0x2545F4914F6CDD1D)
_KEY_SALT = np.uint64(0x5DEECE66D1CE4E5B)
NORMAL_BOUND = 4.33
"""No standard normal this module draws exceeds this in magnitude (:func:`to_normal`)."""
EPISODE = -1
"""The tick value of per-episode draws (never a real tick)."""


def _mix(x: np.ndarray) -> np.ndarray:
    """SplitMix64's finalizer on a uint64 array (wrapping arithmetic)."""
    x = x + _M0
    x = (x ^ (x >> _S30)) * _M1
    x = (x ^ (x >> _S27)) * _M2
    return x ^ (x >> _S31)


def episode_key(rng: np.random.Generator) -> np.uint64:
    """A 64-bit key from a generator's current state, without advancing it.

    The env's generator then draws the same teams and starts at every reality level, so levels
    are compared on paired episodes."""
    raw = np.array([copy.deepcopy(rng.bit_generator).random_raw()], dtype=np.uint64)
    return _mix(raw ^ _KEY_SALT)[0]


def robot_keys(team_key: np.uint64, n: int) -> np.ndarray:
    """(n,) uint64 keys of a team's robots 0 … n-1."""
    idx = np.arange(n, dtype=np.uint64)
    return _mix(np.full(n, team_key, dtype=np.uint64) ^ _mix(idx * _STREAM_MUL + _ROBOT_SALT))


def bits(keys: np.ndarray, ticks: np.ndarray | int, streams: int, first: int = 0) -> np.ndarray:
    """(R, streams) random 64-bit words for robots' keys (R,) at their ticks ((R,) or a scalar):
    streams ``first`` … ``first + streams - 1`` (fewer than 1024 per tick)."""
    t = np.broadcast_to(np.asarray(ticks, dtype=np.int64).astype(np.uint64), keys.shape)
    x = (t * _TICK_MUL)[:, None] + (np.arange(first, first + streams, dtype=np.uint64) * _M0)[None, :]
    x += keys[:, None]
    # SplitMix64's finalizer in place (one temporary)
    y = x >> _S30
    x ^= y
    x *= _M1
    np.right_shift(x, _S27, out=y)
    x ^= y
    x *= _M2
    np.right_shift(x, _S31, out=y)
    x ^= y
    return x


def to_uniform(words: np.ndarray) -> np.ndarray:
    """Uniforms in (0, 1) from random words (the top 53 bits)."""
    out = (words >> _S11).astype(np.float64)
    out += 0.5
    out *= 1.0 / 9007199254740992.0
    return out


_NORMAL_TABLE: np.ndarray | None = None
_S48 = np.uint64(48)


def normal_table() -> np.ndarray:
    """(65536,) the standard normal's quantiles at the midpoints of 65536 equal-probability bins
    (SD 0.99999, largest |value| 4.32), computed on first use."""
    global _NORMAL_TABLE
    if _NORMAL_TABLE is None:
        from statistics import NormalDist

        inv = NormalDist().inv_cdf
        _NORMAL_TABLE = np.array([inv((i + 0.5) / 65536.0) for i in range(65536)])
    return _NORMAL_TABLE


def to_normal(words: np.ndarray) -> np.ndarray:
    """Standard normals from random words: a table lookup on the top 16 bits (the normal
    quantized to 65536 equally likely values, so |value| <= 4.33: a hard bound on the noise)."""
    return np.take(normal_table(), (words >> _S48).astype(np.intp))


def uniforms(keys: np.ndarray, ticks: np.ndarray | int, streams: int, first: int = 0) -> np.ndarray:
    """(R, streams) uniforms in (0, 1) (see :func:`bits`)."""
    return to_uniform(bits(keys, ticks, streams, first))


def normals(keys: np.ndarray, ticks: np.ndarray | int, count: int, first: int = 0) -> np.ndarray:
    """(R, count) standard normals (see :func:`to_normal`)."""
    return to_normal(bits(keys, ticks, count, first))


def tick_draws(keys: np.ndarray, ticks: np.ndarray, n_uniform: int, n_normal: int) -> tuple[np.ndarray, np.ndarray]:
    """A tick's draws for robots' keys (R,) at their ticks (R,): uniforms (R, n_uniform) from
    streams 0 … n_uniform-1 and normals (R, n_normal) from the next streams, as :func:`bits`
    with :func:`to_uniform` and :func:`to_normal` (one compiled pass when the kernels are on)."""
    if not kernels.enabled():
        words = bits(keys, ticks, n_uniform + n_normal)
        return to_uniform(words[:, :n_uniform]), to_normal(words[:, n_uniform:])
    u, n = np.empty((keys.size, n_uniform)), np.empty((keys.size, n_normal))
    rk.reality_draws(keys, ticks, _TICK_MUL, _M0, _M1, _M2, normal_table(), u, n)
    return u, n
