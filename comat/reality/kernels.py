"""Compiled twins (numba) of the reality layer's per-tick numpy code, equal to it bit for bit.

As :mod:`comat.kernels` (same rules: the numpy code in :mod:`comat.reality` is the reference and
runs when :func:`comat.kernels.enabled` is False; same order of arithmetic, no fast-math;
``tests/test_kernels.py`` checks each twin against its reference). Logarithms (the geometric run
lengths) stay in numpy, so the kernels report which robots start a run and the caller draws its
length. Why compiled: the layer's ~40 small numpy calls per tick cost more than its arithmetic.

Shapes: R robots, L slots of a delay ring buffer.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["command_step", "motors_step", "pose_step", "reality_draws"]

_jit = njit(cache=True, nogil=True)

_U64 = np.uint64


@_jit
def reality_draws(keys, ticks, tick_mul, stream_mul, m1, m2, table, uniform, normal):
    """:func:`comat.reality.random.bits` at streams 0 … U+N-1 for keys (R,) at ticks (R,), the
    first U as :func:`~comat.reality.random.to_uniform` into uniform (R, U), the next N as
    :func:`~comat.reality.random.to_normal` (``table``) into normal (R, N). SplitMix64 in
    wrapping uint64 arithmetic, as numpy's."""
    n_u, n_n = uniform.shape[1], normal.shape[1]
    s11, s27, s30, s31, s48 = _U64(11), _U64(27), _U64(30), _U64(31), _U64(48)
    for r in range(keys.size):
        base = _U64(ticks[r]) * tick_mul
        for j in range(n_u + n_n):
            x = base + _U64(j) * stream_mul
            x += keys[r]
            x ^= x >> s30
            x *= m1
            x ^= x >> s27
            x *= m2
            x ^= x >> s31
            if j < n_u:
                f = np.float64(x >> s11)
                f += 0.5
                f *= 1.0 / 9007199254740992.0
                uniform[r, j] = f
            else:
                normal[r, j - n_u] = table[np.intp(x >> s48)]


@_jit
def _motor_wheel(wheel, r, i, dead_zone, gain, fault_scale, c, alpha, step, speed, noise, rho, kick, bound, noise_n):
    target = (0.0 if abs(wheel) < dead_zone[r] else wheel) * gain[r, i]
    if fault_scale is not None:
        target = target * fault_scale[r]
    target = min(max(target, -c), c)
    old = speed[r, i]
    new = target + (old - target) * alpha[r, i]
    if step > 0:
        new = old + min(max(new - old, -step), step)
    speed[r, i] = new
    if noise_n is None:
        return new
    nz = min(max(noise[r, i] * rho + kick * noise_n[r, i], -bound), bound)
    noise[r, i] = nz
    return min(max(new + (nz if target != 0.0 else 0.0), -c), c)


@_jit
def motors_step(
    dxu,
    wheel_radius,
    half_length,
    length,
    dead_zone,
    gain,
    fault_scale,
    cap,
    alpha,
    step,
    speed,
    noise,
    rho,
    kick,
    bound,
    noise_n,
    out,
):
    """:func:`~comat.sim.kinematics.uni_to_diff`, :meth:`comat.reality.motors.Motors.update` and
    :func:`~comat.sim.kinematics.diff_to_uni` in one pass: unicycle commands (R, 2) in, executed
    ones into out (R, 2); wheel speeds ``speed`` and disturbance ``noise`` (R, 2) advanced in
    place. ``dead_zone`` (R,); ``fault_scale`` (R,) or None (no faults); ``noise_n`` (R, 2) or None
    (no disturbance)."""
    for r in range(dxu.shape[0]):
        v, w = dxu[r, 0], dxu[r, 1]
        c = cap[r]
        left = _motor_wheel(
            (v - half_length * w) / wheel_radius,
            r,
            0,
            dead_zone,
            gain,
            fault_scale,
            c,
            alpha,
            step,
            speed,
            noise,
            rho,
            kick,
            bound,
            noise_n,
        )
        right = _motor_wheel(
            (v + half_length * w) / wheel_radius,
            r,
            1,
            dead_zone,
            gain,
            fault_scale,
            c,
            alpha,
            step,
            speed,
            noise,
            rho,
            kick,
            bound,
            noise_n,
        )
        out[r, 0] = wheel_radius * (left + right) / 2.0
        out[r, 1] = wheel_radius * (right - left) / length


@_jit
def command_step(sent_now, ticks, delay, sent, last, lost_run, lost_left, loss_prob, brake_after, u, starts, out):
    """:meth:`comat.reality.paths.CommandPath.update` for commands sent now (R, 2) into out (R, 2),
    its state (``sent`` ring (R, L, 2), ``last``, ``lost_run``, ``lost_left``) advanced in place,
    except the length of each loss run that starts this tick: returns k, the number of such
    robots, whose rows are starts[:k] (the caller draws their ``lost_left``; logarithms stay in
    numpy)."""
    L = sent.shape[1]
    k = 0
    for r in range(sent_now.shape[0]):
        t = ticks[r]
        if L > 1:
            slot = t % L
            sent[r, slot, 0], sent[r, slot, 1] = sent_now[r, 0], sent_now[r, 1]
            if t >= delay[r]:
                j = (t - delay[r]) % L
                ax, ay = sent[r, j, 0], sent[r, j, 1]
            else:
                ax, ay = 0.0, 0.0
        else:
            ax, ay = sent_now[r, 0], sent_now[r, 1]
        if loss_prob <= 0:
            last[r, 0], last[r, 1] = ax, ay
            out[r, 0], out[r, 1] = ax, ay
            lost_run[r] = 0  # (only a missed tick of the script loses a command then: the numpy path)
            continue
        lost = lost_left[r] > 0
        if lost:
            lost_left[r] -= 1
        elif u[r, 0] < loss_prob:
            lost = True
            starts[k] = r
            k += 1
        if lost:
            lost_run[r] += 1
        else:
            lost_run[r] = 0
            last[r, 0], last[r, 1] = ax, ay
        if lost_run[r] >= brake_after:
            out[r, 0], out[r, 1] = 0.0, 0.0
        else:
            out[r, 0], out[r, 1] = last[r, 0], last[r, 1]
    return k


@_jit
def pose_step(
    true, ticks, history, delay, bias, scale, noise, measured, freeze_left, freeze_prob, hold_prob, u, starts
):
    """:meth:`comat.reality.paths.PosePath.update` for true poses (R, 3): the ``history`` ring
    (R, L, 3), ``freeze_left`` and ``measured`` (R, 3) advanced in place (``noise`` (R, 3) or
    None), except the length of each freeze that starts this tick: returns k, the number of
    such robots, whose rows are starts[:k] (the caller draws their ``freeze_left``)."""
    L = history.shape[1]
    k = 0
    for r in range(true.shape[0]):
        if L > 1:
            slot = ticks[r] % L
            history[r, slot, 0], history[r, slot, 1], history[r, slot, 2] = true[r, 0], true[r, 1], true[r, 2]
            j = (slot - delay[r]) % L
            x, y, th = history[r, j, 0], history[r, j, 1], history[r, j, 2]
        else:
            x, y, th = true[r, 0], true[r, 1], true[r, 2]
        if noise is not None:
            x = x + noise[r, 0] * scale[r, 0]
            y = y + noise[r, 1] * scale[r, 1]
            th = th + noise[r, 2] * scale[r, 2]
        x += bias[r, 0]
        y += bias[r, 1]
        if noise is not None:  # Python's float modulo is numpy's remainder (fmod, then the sign fix)
            th = np.pi - (np.pi - th) % (2.0 * np.pi)
        frozen = freeze_left[r] > 0
        if frozen:
            freeze_left[r] -= 1
        elif freeze_prob > 0 and u[r, 1] < freeze_prob:
            frozen = True
            starts[k] = r
            k += 1
        if hold_prob > 0 and u[r, 0] < hold_prob:
            frozen = True
        if not frozen:
            measured[r, 0], measured[r, 1], measured[r, 2] = x, y, th
    return k
