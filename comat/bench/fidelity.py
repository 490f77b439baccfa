"""How closely the MuJoCo robot follows the Robotarium's unicycle model (tests and ``comat bench fidelity``).

Two measurements:

* steady state: hold a wheel-speed command and compare the achieved forward speed, yaw rate
  and lateral (sideways) speed with the command, over a grid of the whole admissible range;
* trajectories: 10 s of random piecewise-constant commands (pieces of 0.5–2 s, wheel speeds
  uniform in ±12.5 rad/s, i.e. the whole admissible set), simulated in MuJoCo and integrated
  the Robotarium's way (forward Euler at 0.033 s); also against the exact unicycle (arcs).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from comat import constants as C
from comat.config import SimConfig
from comat.sim import World
from comat.sim.kinematics import diff_to_uni, euler_unicycle_step

__all__ = [
    "SteadyState",
    "exact_unicycle",
    "random_commands",
    "robotarium_euler",
    "simulate",
    "steady_state",
    "trajectory_errors",
]

_DT = C.CONTROL_DT_S


def random_commands(rng: np.random.Generator, duration_s: float = 10.0, profile=C.DEFAULT_PROFILE) -> np.ndarray:
    """(T, 2) piecewise-constant [v, ω] commands: pieces of 15–60 ticks, wheels uniform in ±max."""
    n = round(duration_s / _DT)
    out = np.empty((n, 2))
    k = 0
    lim = profile.max_wheel_velocity_radps
    while k < n:
        hold = int(rng.integers(15, 61))
        out[k : k + hold] = diff_to_uni(rng.uniform(-lim, lim, 2), profile)
        k += hold
    return out


def robotarium_euler(start: np.ndarray, commands: np.ndarray) -> np.ndarray:
    """(T+1, 3) poses of the Robotarium simulator's forward-Euler integration."""
    poses = [np.asarray(start, float)]
    for dxu in commands:
        poses.append(euler_unicycle_step(poses[-1], dxu))
    return np.array(poses)


def exact_unicycle(start: np.ndarray, commands: np.ndarray) -> np.ndarray:
    """(T+1, 3) poses of the exact unicycle (circular arcs) under the same commands."""
    poses = [np.asarray(start, float)]
    for v, w in commands:
        x, y, th = poses[-1]
        if abs(w) < 1e-12:
            nxt = (x + v * _DT * np.cos(th), y + v * _DT * np.sin(th), th)
        else:
            nxt = (
                x + v / w * (np.sin(th + w * _DT) - np.sin(th)),
                y - v / w * (np.cos(th + w * _DT) - np.cos(th)),
                th + w * _DT,
            )
        poses.append(np.array(nxt))
    return np.array(poses)


def simulate(world: World, start: np.ndarray, commands: np.ndarray) -> np.ndarray:
    """(T+1, 3) poses of a single-robot ``world`` driven by the commands (heading unwrapped)."""
    world.reset(start[None])
    poses = [world.poses[0]]
    for dxu in commands:
        world.step(dxu[None])
        poses.append(world.poses[0])
    out = np.array(poses)
    out[:, 2] = np.unwrap(out[:, 2])
    return out


def _inside(poses: np.ndarray, margin: float = 0.2) -> bool:
    x0, x1, y0, y1 = C.ARENA_BOUNDS_M
    return bool(
        np.all(
            (poses[:, 0] > x0 + margin)
            & (poses[:, 0] < x1 - margin)
            & (poses[:, 1] > y0 + margin)
            & (poses[:, 1] < y1 - margin)
        )
    )


def trajectory_errors(config: SimConfig, seeds: range | list[int]) -> dict[str, np.ndarray]:
    """Per seed, the largest position error (m) of MuJoCo vs Euler, MuJoCo vs exact, Euler vs exact.

    Each seed draws command sequences until the Euler path stays 0.2 m inside the arena
    ("away from contacts"); the robot starts at the centre heading +x.
    """
    world = World(1, config)
    start = np.zeros(3)
    out = {"mujoco_vs_euler": [], "mujoco_vs_exact": [], "euler_vs_exact": []}
    for seed in seeds:
        rng = np.random.default_rng(seed)
        while True:
            cmds = random_commands(rng)
            euler = robotarium_euler(start, cmds)
            if _inside(euler):
                break
        exact = exact_unicycle(start, cmds)
        sim = simulate(world, start, cmds)
        err = lambda a, b: float(np.max(np.linalg.norm(a[:, :2] - b[:, :2], axis=1)))
        out["mujoco_vs_euler"].append(err(sim, euler))
        out["mujoco_vs_exact"].append(err(sim, exact))
        out["euler_vs_exact"].append(err(euler, exact))
    return {k: np.array(v) for k, v in out.items()}


@dataclass
class SteadyState:
    """Worst steady-state tracking over the grid of commands.

    Attributes:
        rel_error: max over commands of the relative error of v and ω (each vs its command).
        abs_error: max absolute error of v (m/s) and ω (rad/s).
        lateral_mps: max sideways speed of the axle centre (m/s).
    """

    rel_error: float
    abs_error: float
    lateral_mps: float


def steady_state(config: SimConfig, grid: int = 9, settle_s: float = 1.0, measure_s: float = 1.0) -> SteadyState:
    """Hold each wheel-speed pair of a grid×grid lattice over ±12.5 rad/s and measure the motion.

    v, ω and the lateral speed come from the pose change over each control tick (chord of the
    arc, corrected to arc length), averaged over nothing: the worst tick counts.
    """
    world = World(1, config)
    prof = world.profile
    lim = prof.max_wheel_velocity_radps
    wheels = np.linspace(-lim, lim, grid)
    rel = absolute = lateral = 0.0
    n_settle, n_meas = round(settle_s / _DT), round(measure_s / _DT)
    for left in wheels:
        for right in wheels:
            if left == 0 and right == 0:
                continue
            v, w = diff_to_uni(np.array([left, right]), prof)
            world.reset(np.zeros((1, 3)))
            cmd = np.array([[v, w]])
            for _ in range(n_settle):
                world.step(cmd)
            track = [world.poses[0]]
            for _ in range(n_meas):
                world.step(cmd)
                track.append(world.poses[0])
            p = np.array(track)
            th = np.unwrap(p[:, 2])
            dth = np.diff(th)
            mid = 0.5 * (th[1:] + th[:-1])
            dp = np.diff(p[:, :2], axis=0)
            along = dp[:, 0] * np.cos(mid) + dp[:, 1] * np.sin(mid)
            side = -dp[:, 0] * np.sin(mid) + dp[:, 1] * np.cos(mid)
            half = 0.5 * dth
            arc = np.where(np.abs(half) > 1e-12, half / np.sin(np.where(np.abs(half) > 1e-12, half, 1.0)), 1.0)
            v_meas, w_meas = along * arc / _DT, dth / _DT
            err_v, err_w = np.max(np.abs(v_meas - v)), np.max(np.abs(w_meas - w))
            absolute = max(absolute, err_v, err_w)
            rel = max(rel, err_v / abs(v) if abs(v) > 1e-9 else 0.0, err_w / abs(w) if abs(w) > 1e-9 else 0.0)
            lateral = max(lateral, float(np.max(np.abs(side))) / _DT)
    return SteadyState(rel_error=rel, abs_error=absolute, lateral_mps=lateral)
