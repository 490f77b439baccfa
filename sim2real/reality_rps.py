"""An exported main.py under rps, with the reality layer around ``get_poses`` and ``set_velocities``.

``python -m sim2real.reality_rps --reality LEVEL|PROFILE --seed S [--drive rps|unicycle|wheels] -- main.py
[ARGS]`` (``comat export --check DIR --reality ...`` runs it in the folder, a subprocess per run).
It replaces ``rps.robotarium.Robotarium`` — whichever generation is importable: the installed legacy
rps, or V2 through ``PYTHONPATH`` — by a subclass, then runs main.py unchanged:

* ``get_poses`` returns what the script would measure (:class:`comat.reality.RealityLayer`: late,
  noisy, held or frozen poses), while rps keeps the true ones;
* the commands ``set_velocities`` receives are judged by rps as sent (its actuator check), then
  pass the layer's command path and motors (delay, loss, brake, lag, dead zone, gains, faults),
  and the robots execute those: rps integrates them (``--drive rps``) or comat's MuJoCo world
  steps them with contacts (``--drive unicycle|wheels``; rps's poses are then MuJoCo's);
* rps's own checks (boundary, collision, actuator) and this module's read true poses: the closest
  offset centres, pair-iterations within the Robotarium's collision distance (the first one
  named by iteration and robots), MuJoCo contacts.

V2 drives the robots from their chargers to the start poses inside its constructor. The layer
starts after that drive (with its own start error off: the drive's tolerance, 5 cm and 0.2 rad,
is the start error): under the layer's dead zone the drive's last small commands do not turn the
wheels and its loop would never end (the firmware's integral action creeps there instead, which
the layer does not model). The legacy simulator starts at the poses, so the layer's start error
moves them first. After
main.py returns, one line ``COMAT_REALITY {json}`` reports the run.
"""

from __future__ import annotations

import argparse
import atexit
import dataclasses
import json
import runpy
import sys
from pathlib import Path

import numpy as np

from comat import constants as C
from comat.config import SimConfig
from comat.reality import RealityConfig, RealityLayer, resolve_reality
from comat.sim import World
from comat.sim.kinematics import threshold_wheels
from comat.sim.layout import team_layout

__all__ = ["DRIVES", "install", "main"]

DRIVES = ("rps", "unicycle", "wheels")
"""What moves the robots: rps's own integration, or comat's MuJoCo world in either tier."""


class _Run:
    """The layer, the optional MuJoCo world and the true-pose record of one run."""

    def __init__(self, reality: RealityConfig, seed: int, drive: str) -> None:
        self.reality, self.seed, self.drive = reality, seed, drive
        self.layer: RealityLayer | None = None
        self.world = None
        self.executed: np.ndarray | None = None
        self.iterations = 0
        self.min_offset_distance = float("inf")
        self.collision_pair_iterations = 0
        self.first_collision: dict | None = None
        self.contact_ticks = 0
        self.boundary_iterations = 0

    def report(self) -> dict:
        return {
            "reality": self.reality.level,
            "overrides": self.reality.overrides(),
            "seed": self.seed,
            "drive": self.drive,
            "iterations": self.iterations,
            "min_offset_centre_distance_m": None
            if not np.isfinite(self.min_offset_distance)
            else self.min_offset_distance,
            "collision_pair_iterations": self.collision_pair_iterations,
            "first_collision": self.first_collision,
            "mujoco_contact_ticks": self.contact_ticks if self.drive != "rps" else None,
            "boundary_iterations": self.boundary_iterations,
        }


def install(reality: RealityConfig, seed: int, drive: str = "rps") -> _Run:
    """Replace ``rps.robotarium.Robotarium`` by one with the reality layer; returns the run's record."""
    import rps.robotarium as module

    base = module.Robotarium
    v2 = hasattr(base, "debug")
    profile = C.GTERNAL if v2 else C.GRITSBOT  # the generation's robot (axle 0.11 or 0.105 m)
    if v2:  # V2's start-up drive leaves the start error itself
        reality = dataclasses.replace(reality, start_xy_m=0.0, start_theta_rad=0.0)
    run = _Run(reality, seed, drive)

    class RealityRobotarium(base):
        """rps's Robotarium with the reality layer between it and the script (module docstring)."""

        def _true(self) -> np.ndarray:
            return self._poses if v2 else self.poses

        def _set_true(self, poses: np.ndarray) -> None:
            if v2:
                self._poses = np.array(poses, dtype=float)
            else:
                self.poses[:] = poses

        def _begin(self) -> None:
            n = self.number_of_robots
            run.layer = RealityLayer(run.reality, profile, team_layout((n,)), run.seed)
            start = run.layer.start(np.array(self._true(), dtype=float).T, np.array([0]), None)
            self._set_true(start.T)
            if run.drive != "rps":
                run.world = World(n, SimConfig(tier=run.drive, profile=profile.name))
                run.world.reset(start)
            run.layer.begin_measuring(np.array(self._true(), dtype=float).T.copy(), np.array([0]))

        def _driving_in(self) -> bool:
            """V2's start-up drive is under way (the layer waits for its end)."""
            return bool(getattr(self, "initializing", False))

        def get_poses(self):
            true = super().get_poses()  # rps's call-order checks
            if self._driving_in():
                return true
            if run.layer is None:
                self._begin()
            return run.layer.measured.T.copy()

        def _validate(self, *args, **kwargs):
            errors = super()._validate(*args, **kwargs)  # rps judges true poses and the commands as sent
            if self._driving_in():
                return errors
            name = "_velocities" if v2 else "velocities"
            sent = np.array(getattr(self, name), dtype=float).T
            clipped, _ = threshold_wheels(sent, profile)
            run.executed = run.layer.actuate(clipped)
            # rps integrates what the robots execute (nothing when MuJoCo moves them)
            setattr(self, name, np.zeros_like(sent.T) if run.drive != "rps" else run.executed.T.copy())
            return errors

        def step(self):
            super().step()
            if self._driving_in() or run.layer is None:
                return
            if run.world is not None:
                events = run.world.step(run.executed)
                run.contact_ticks += int(events.robot_contact.any())
                self._set_true(run.world.poses.T)
            true = np.array(self._true(), dtype=float).T
            run.layer.observe(true.copy())
            run.iterations += 1
            _judge(run, true)

    module.Robotarium = RealityRobotarium
    return run


def _judge(run: _Run, true: np.ndarray) -> None:
    """The Robotarium's checks on true poses (N, 3): offset centres, collisions, boundary."""
    n = true.shape[0]
    x0, x1, y0, y1 = C.ARENA_BOUNDS_M
    out = (true[:, 0] < x0) | (true[:, 0] > x1) | (true[:, 1] < y0) | (true[:, 1] > y1)
    run.boundary_iterations += int(out.any())
    if n < 2:
        return
    centres = true[:, :2] + C.COLLISION_OFFSET_M * np.column_stack([np.cos(true[:, 2]), np.sin(true[:, 2])])
    i, j = np.triu_indices(n, 1)
    d = np.hypot(*(centres[i] - centres[j]).T)
    run.min_offset_distance = min(run.min_offset_distance, float(d.min()))
    hit = d <= C.COLLISION_DIAMETER_M
    run.collision_pair_iterations += int(hit.sum())
    if hit.any() and run.first_collision is None:
        k = int(np.flatnonzero(hit)[0])
        run.first_collision = {"iteration": run.iterations, "robots": [int(i[k]), int(j[k])], "distance_m": float(d[k])}


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="python -m sim2real.reality_rps", description=__doc__.splitlines()[0])
    parser.add_argument("--reality", required=True, help="a level (off, nominal, stress) or a profile.yaml")
    parser.add_argument("--seed", type=int, default=0, help="the layer's seed (default: %(default)s)")
    parser.add_argument("--drive", choices=DRIVES, default="rps", help="what moves the robots (default: %(default)s)")
    parser.add_argument("script", help="the exported main.py")
    parser.add_argument("args", nargs=argparse.REMAINDER, help="main.py's arguments")
    a = parser.parse_args(argv)
    run = install(resolve_reality(a.reality, "--reality"), a.seed, a.drive)
    atexit.register(lambda: print("COMAT_REALITY " + json.dumps(run.report()), flush=True))
    script = Path(a.script).resolve()
    sys.path.insert(0, str(script.parent))
    sys.argv = [str(script), *a.args]
    runpy.run_path(str(script), run_name="__main__")


if __name__ == "__main__":
    main()
