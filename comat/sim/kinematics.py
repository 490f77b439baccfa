"""Differential-drive kinematics, pure numpy, vectorized over any leading batch dimensions.

Naming follows the Robotarium: ``dxu`` unicycle commands [v (m/s), ω (rad/s)], ``dxdd`` wheel
speeds [left, right] (rad/s), ``dxi`` single-integrator velocities [ẋ, ẏ] (m/s) of the point
``projection_distance`` ahead of the axle centre, ``poses`` [x, y, θ]. Arrays are
row-per-robot: ``(..., N, 2)`` or ``(..., N, 3)``.

These functions are the hot path and do not validate; the public classes that call them do.
Flat (R, 2) float inputs go to their compiled twins in :mod:`comat.kernels` (same bits).
"""

from __future__ import annotations

import numpy as np

from comat import constants as C
from comat import kernels

__all__ = [
    "WHEEL_LIMIT_TOLERANCE",
    "diff_to_uni",
    "euler_unicycle_step",
    "limit_to_wheels",
    "projected_points",
    "si_to_uni",
    "threshold_wheels",
    "uni_to_diff",
    "uni_to_si",
    "wheel_rhombus",
    "wrap_angle",
]

WHEEL_LIMIT_TOLERANCE = 1.0 + 1e-9
"""A wheel overruns its limit beyond ``limit · WHEEL_LIMIT_TOLERANCE``: commands exactly at the
limit, up to rounding, are not actuator errors."""


def wrap_angle(theta: np.ndarray) -> np.ndarray:
    """Angles wrapped to (-π, π], as rps does with atan2(sin, cos)."""
    return np.arctan2(np.sin(theta), np.cos(theta))


def uni_to_diff(dxu: np.ndarray, profile: C.RobotProfile = C.DEFAULT_PROFILE) -> np.ndarray:
    """Wheel speeds (..., N, 2) [left, right] for unicycle commands (..., N, 2) [v, ω]."""
    r, half_l = profile.wheel_radius_m, profile.base_length_m / 2.0
    v, w = dxu[..., 0], dxu[..., 1]
    return np.stack([(v - half_l * w) / r, (v + half_l * w) / r], axis=-1)


def diff_to_uni(dxdd: np.ndarray, profile: C.RobotProfile = C.DEFAULT_PROFILE) -> np.ndarray:
    """Unicycle commands (..., N, 2) [v, ω] for wheel speeds (..., N, 2) [left, right]."""
    r, l = profile.wheel_radius_m, profile.base_length_m
    left, right = dxdd[..., 0], dxdd[..., 1]
    return np.stack([r * (left + right) / 2.0, r * (right - left) / l], axis=-1)


def threshold_wheels(dxu: np.ndarray, profile: C.RobotProfile = C.DEFAULT_PROFILE) -> tuple[np.ndarray, np.ndarray]:
    """Clip each wheel to ±12.5 rad/s independently, as rps ``step()`` does since 2024.

    Returns:
        dxu_clipped: (..., N, 2) the command the wheels can realize.
        overrun: (..., N) bool, True where a wheel of the *requested* command exceeded the
            limit (the Robotarium's actuator error).
    """
    limit = profile.max_wheel_velocity_radps
    if _flat(dxu):
        out, overrun = np.empty_like(dxu), np.empty(dxu.shape[0], dtype=bool)
        r, length = profile.wheel_radius_m, profile.base_length_m
        any_over = kernels.threshold_wheels(dxu, r, length / 2.0, length, limit, WHEEL_LIMIT_TOLERANCE, out, overrun)
        return (out if any_over else dxu), overrun
    dxdd = uni_to_diff(dxu, profile)
    over = np.abs(dxdd) > limit * WHEEL_LIMIT_TOLERANCE
    overrun = over[..., 0] | over[..., 1]
    if not overrun.any():  # the usual case behind the safety filter: nothing to clip
        return dxu, overrun
    # Robots within the limit keep their command bit for bit (no round trip through the wheels).
    return np.where(overrun[..., None], diff_to_uni(np.clip(dxdd, -limit, limit), profile), dxu), overrun


def projected_points(poses: np.ndarray, distance: float = C.PROJECTION_DISTANCE_M) -> np.ndarray:
    """Points ``distance`` ahead of each axle centre along its heading, (..., N, 2)."""
    th = poses[..., 2]
    return poses[..., :2] + distance * np.stack([np.cos(th), np.sin(th)], axis=-1)


def uni_to_si(dxu: np.ndarray, poses: np.ndarray, distance: float = C.PROJECTION_DISTANCE_M) -> np.ndarray:
    """Velocity (..., N, 2) of the projected point for unicycle commands (..., N, 2)."""
    c, s = np.cos(poses[..., 2]), np.sin(poses[..., 2])
    v, lw = dxu[..., 0], distance * dxu[..., 1]
    return np.stack([c * v - s * lw, s * v + c * lw], axis=-1)


def si_to_uni(
    dxi: np.ndarray,
    poses: np.ndarray,
    distance: float = C.PROJECTION_DISTANCE_M,
    cos_sin: tuple[np.ndarray, np.ndarray] | None = None,
) -> np.ndarray:
    """Unicycle commands (..., N, 2) that move the projected point with velocity ``dxi``.

    The exact inverse of :func:`uni_to_si` (rps ``create_si_to_uni_mapping`` without its ω clip):
    v = cosθ·ẋ + sinθ·ẏ, ω = (−sinθ·ẋ + cosθ·ẏ)/distance. ``cos_sin`` may pass the headings'
    cosines and sines when the caller has them already.
    """
    c, s = cos_sin if cos_sin is not None else (np.cos(poses[..., 2]), np.sin(poses[..., 2]))
    if _flat(dxi):
        out = np.empty_like(dxi)
        kernels.si_to_uni(dxi, c, s, distance, out)
        return out
    dx, dy = dxi[..., 0], dxi[..., 1]
    return np.stack([c * dx + s * dy, (-s * dx + c * dy) / distance], axis=-1)


def wheel_rhombus(
    distance: float, profile: C.RobotProfile = C.DEFAULT_PROFILE, fraction: float = 1.0
) -> tuple[float, float]:
    """(k, v) of the per-wheel limit seen at the projected point: |a| + k|b| <= v for velocity
    components a along and b across the heading, k = l_axle / (2·distance) (1), v =
    r·φ̇_max·fraction (m/s)."""
    return profile.base_length_m / (
        2.0 * distance
    ), profile.wheel_radius_m * profile.max_wheel_velocity_radps * fraction


def limit_to_wheels(
    dxi: np.ndarray,
    poses: np.ndarray,
    distance: float = C.PROJECTION_DISTANCE_M,
    profile: C.RobotProfile = C.DEFAULT_PROFILE,
    fraction: float = 1.0,
    cos_sin: tuple[np.ndarray, np.ndarray] | None = None,
) -> np.ndarray:
    """Closest projected-point velocities (..., 2) that the wheels can realize.

    Through the projection map, the per-wheel limit |φ̇| <= φ̇_max is the rhombus
    |a| + k|b| <= r·φ̇_max·fraction (a, b: components along and across the heading,
    k = l_axle / (2·distance)); points outside are projected onto it (closed form).
    """
    k, v = wheel_rhombus(distance, profile, fraction)
    c, s = cos_sin if cos_sin is not None else (np.cos(poses[..., 2]), np.sin(poses[..., 2]))
    if _flat(dxi):
        out = np.empty_like(dxi)
        kernels.limit_to_wheels(dxi, c, s, k, v, out)
        return out
    ux, uy = dxi[..., 0], dxi[..., 1]
    a = c * ux + s * uy
    b = c * uy - s * ux
    pa, pb = np.abs(a), np.abs(b)
    outside = pa + k * pb > v
    # (|a|, |b|) onto the edge from (v, 0) to (0, v/k), clamped to its ends.
    t = np.clip(((v - pa) * v + pb * v / k) / (v * v * (1.0 + 1.0 / (k * k))), 0.0, 1.0)
    pa = np.where(outside, v - t * v, pa)
    pb = np.where(outside, t * v / k, pb)
    a = np.copysign(pa, a)
    b = np.copysign(pb, b)
    return np.stack([c * a - s * b, s * a + c * b], axis=-1)


def _flat(a: np.ndarray) -> bool:
    """Whether a goes to the compiled twin: (R, 2) float64, kernels on."""
    return kernels.enabled() and a.ndim == 2 and a.dtype == np.float64


def euler_unicycle_step(poses: np.ndarray, dxu: np.ndarray, dt: float = C.CONTROL_DT_S) -> np.ndarray:
    """The Robotarium simulator's integration of one step: forward Euler, heading wrapped."""
    th = poses[..., 2]
    out = np.empty_like(poses)
    out[..., 0] = poses[..., 0] + dt * dxu[..., 0] * np.cos(th)
    out[..., 1] = poses[..., 1] + dt * dxu[..., 0] * np.sin(th)
    out[..., 2] = wrap_angle(th + dt * dxu[..., 1])
    return out
