"""The reality layer: what separates comat's simulated robots from the Robotarium's real ones.

Spec sheet (defaults and their provenance, read from the Robotarium's firmware, tracker and
simulator code: :data:`SOURCES`, :mod:`comat.reality.config`; the § numbers there name sections of
docs/reality-sources.md, which gives each fact with its public source):

* **pose path** — per-robot measurement delay (whole ticks), Gaussian position/heading noise, a
  per-episode position bias, held measurements and tracking freezes that repeat the last
  measured pose (:class:`PosePath`);
* **command path** — per-robot command delay (whole ticks), lost commands that leave the last
  one in force, a brake after 0.5 s without a command (:class:`CommandPath`);
* **motors** — first-order wheel-speed lag with an acceleration limit, a low-speed dead zone,
  per-wheel gain mismatch and a top-speed derate drawn per robot and episode, a bounded
  Ornstein–Uhlenbeck wheel disturbance, and faults: one robot per episode running at a fraction
  of its speed from a random tick (:class:`Motors`);
* **start** — the initial-pose error of the Robotarium's initializer (0.05 m, 0.2 rad);
* **physics** (wheels tier) — per-robot wheel–floor friction, chassis mass and centre of mass,
  written into each simulation's own model fields (:meth:`comat.sim.BatchWorld.set_robot_physics`).

Levels ``off`` (the ideal world, bit for bit: :class:`IdentityReality` passes everything through),
``nominal`` and ``stress`` (:data:`LEVELS`); every field overridable on its own (:class:`RealityConfig`).
Everything that decides (policy observations, waypoint controller, safety filter) reads measured poses;
everything that judges (contacts, Robotarium checks, task progress, rewards) reads true ones
(:class:`comat.control.SafeTeams`, :class:`comat.envs.core.TaskCore`); the filter is made robust
to the layer's bounds (:mod:`comat.reality.margin`). Not modelled: tick stretch (a slow loop
stretches the 0.033 s iteration: the Robotarium user guide's section 2.8, docs/reality-sources.md
§6 #11).
"""

from comat.reality.config import LEVELS, REALITY_LEVELS, SOURCES, RealityConfig, resolve_reality
from comat.reality.layer import IdentityReality, RealityLayer
from comat.reality.motors import Motors
from comat.reality.paths import CommandPath, PosePath
from comat.reality.random import episode_key

__all__ = [
    "LEVELS",
    "REALITY_LEVELS",
    "SOURCES",
    "CommandPath",
    "IdentityReality",
    "Motors",
    "PosePath",
    "RealityConfig",
    "RealityLayer",
    "episode_key",
    "resolve_reality",
]
