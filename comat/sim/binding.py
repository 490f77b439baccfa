"""Names resolved once into index arrays: poses in and out of ``qpos``, commands into ``ctrl``.

A :class:`Binding` knows one compiled scene (team size, tier); the hot path only slices arrays.
All methods accept extra leading batch dimensions (the batched world passes (S, nq) arrays).
"""

from __future__ import annotations

import mujoco
import numpy as np

from comat import constants as C

__all__ = ["Binding"]


class Binding:
    """Index arrays and conversions for a scene of ``n_robots`` robots of ``tier``."""

    def __init__(self, model: mujoco.MjModel, n_robots: int, tier: str, profile: C.RobotProfile) -> None:
        self.model = model
        self.n_robots = n_robots
        self.tier = tier
        self.profile = profile
        self.substeps = round(C.CONTROL_DT_S / model.opt.timestep)
        root = "root" if tier == "wheels" else "x"
        self.qadr = np.array([model.jnt_qposadr[model.joint(f"robot_{i}/{root}").id] for i in range(n_robots)])
        self.dadr = np.array([model.jnt_dofadr[model.joint(f"robot_{i}/{root}").id] for i in range(n_robots)])
        # Wheel hinge angles of the wheeled tier are reset to 0 (irrelevant to the dynamics).
        self.wheel_qadr = (
            np.array(
                [
                    model.jnt_qposadr[model.joint(f"robot_{i}/{s}_wheel").id]
                    for i in range(n_robots)
                    for s in ("left", "right")
                ]
            )
            if tier == "wheels"
            else np.zeros(0, np.int64)
        )
        self.body = np.array([model.body(f"robot_{i}/chassis").id for i in range(n_robots)])
        self.wheel_geoms = (
            np.array([[model.geom(f"robot_{i}/{s}_wheel").id for s in ("left", "right")] for i in range(n_robots)])
            if tier == "wheels"
            else np.zeros((0, 2), np.int64)
        )
        """(N, 2) each robot's wheel geoms (wheels tier; their friction is the wheel-floor contact's)."""
        self.sensor_all = np.array([model.sensor_adr[model.sensor(f"robot_{i}/contacts").id] for i in range(n_robots)])
        self.sensor_wall = np.array(
            [model.sensor_adr[model.sensor(f"robot_{i}/wall_contacts").id] for i in range(n_robots)]
        )
        self.half_timestep = 0.5 * model.opt.timestep
        self.wheel_geometry = (profile.wheel_radius_m, profile.base_length_m / 2.0)
        """(wheel radius, half axle length) (m), as :meth:`ctrl` uses them."""
        self.lateral_gain = 0.0
        if tier == "unicycle":
            gain = model.actuator_gainprm[model.actuator("robot_0/forward").id, 0]
            self._mass = float(model.body_subtreemass[self.body[0]])
            self._h_kv = model.opt.timestep * gain
            self.lateral_gain = (2.0 * self._mass + self._h_kv) / self._h_kv
        self.z0 = profile.wheel_radius_m
        self._pose_cols = (self.qadr[:, None] + np.arange(7 if tier == "wheels" else 3)).ravel()

    def physics_fields(
        self, friction: np.ndarray, mass_scale: np.ndarray, com_xy: np.ndarray, base: mujoco.MjModel
    ) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Per-robot physics of the wheels tier as model-field writes: {field: (index, values)}
        for wheel friction (N,) (wheel-floor μ: the wheel geoms have the contact's priority),
        chassis mass scale (N,) and centre-of-mass offset (N, 2) (m), relative to ``base``."""
        return {
            "geom_friction": (self.wheel_geoms, np.repeat(friction[:, None], 2, axis=1)),
            "body_mass": (self.body, base.body_mass[self.body] * mass_scale),
            "body_ipos": (self.body, base.body_ipos[self.body] + np.column_stack([com_xy, np.zeros(len(com_xy))])),
        }

    # -- poses ------------------------------------------------------------------------------------
    def poses(self, qpos: np.ndarray) -> np.ndarray:
        """(..., N, 3) [x, y, θ] from (..., nq) qpos; θ in (-π, π]."""
        q = np.take(qpos, self._pose_cols, axis=-1).reshape(*qpos.shape[:-1], self.n_robots, -1)
        if self.tier == "wheels":
            w, x, y, z = q[..., 3], q[..., 4], q[..., 5], q[..., 6]
            yaw = np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
        else:
            yaw = np.pi - np.remainder(np.pi - q[..., 2], 2.0 * np.pi)  # wrapped to (-π, π]
        return np.stack([q[..., 0], q[..., 1], yaw], axis=-1)

    def write_poses(self, qpos: np.ndarray, poses: np.ndarray) -> None:
        """Write (..., N, 3) poses at rest into (..., nq) qpos (wheels upright on the floor)."""
        x, y, th = poses[..., 0], poses[..., 1], poses[..., 2]
        if self.tier == "wheels":
            cols = self.qadr[:, None] + np.arange(7)
            vals = np.stack(
                [x, y, np.full_like(x, self.z0), np.cos(th / 2), np.zeros_like(x), np.zeros_like(x), np.sin(th / 2)],
                axis=-1,
            )
            qpos[..., cols] = vals
            qpos[..., self.wheel_qadr] = 0.0
        else:
            qpos[..., self.qadr[:, None] + np.arange(3)] = np.stack([x, y, th], axis=-1)

    # -- commands ---------------------------------------------------------------------------------
    def ctrl(self, dxu: np.ndarray) -> np.ndarray:
        """(..., nu) actuator targets for unicycle commands (..., N, 2) the wheels can realize.

        Wheeled tier: wheel speeds [left, right] per robot. Unicycle tier: body-frame servo
        targets [forward, lateral, yaw rate], corrected so that in steady state the integrated
        motion is the exact unicycle arc (docs/physics.md): the lateral target supplies the
        centripetal force and both undo the semi-implicit integrator's lag of one substep.
        """
        v, w = dxu[..., 0], dxu[..., 1]
        if self.tier == "wheels":
            r, half_l = self.wheel_geometry
            return np.stack([(v - half_l * w) / r, (v + half_l * w) / r], axis=-1).reshape(*dxu.shape[:-2], -1)
        # a = ωh/2 is tiny (|a| < 0.03 at 3.8 rad/s and h = 11 ms): series to machine precision
        # (next terms < 1e-14) instead of sin, cos and a division.
        a = self.half_timestep * w
        a2 = a * a
        sinc_a = 1.0 - a2 * (1.0 / 6.0 - a2 * (1.0 / 120.0 - a2 / 5040.0))  # sin(a)/a
        cos_a = 1.0 - a2 * (0.5 - a2 * (1.0 / 24.0 - a2 / 720.0))
        forward = v * sinc_a * cos_a
        lateral = v * sinc_a * sinc_a * a * self.lateral_gain
        return np.stack([forward, lateral, w], axis=-1).reshape(*dxu.shape[:-2], -1)

    # -- contacts ---------------------------------------------------------------------------------
    def contacts(self, sensordata: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(..., N) bool robot–robot and robot–wall contact flags from (..., nsensordata)."""
        total = np.take(sensordata, self.sensor_all, axis=-1)
        wall = np.take(sensordata, self.sensor_wall, axis=-1)
        return total > wall, wall > 0

    def contacts_any(self, record: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(S, N) flags: contact in any substep of a (S, substeps, nsensordata) recording."""
        total = np.take(record, self.sensor_all, axis=-1)
        wall = np.take(record, self.sensor_wall, axis=-1)
        return (total - wall).max(axis=1) > 0, wall.max(axis=1) > 0
