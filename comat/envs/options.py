"""The options every environment API shares: one frozen :class:`EnvOptions`.

``comat.make_env(env_id, **options)``, ``comat.make_vec_env(env_id, num_envs, **options)``,
:class:`~comat.envs.base.TaskEnv` and :class:`~comat.envs.vector.VectorEnv` take these options as
keywords and build one EnvOptions from them; :func:`comat.envs.registry.check_options` names the
valid options from its fields. Beside them each API takes a few of its own: the task's options
(e.g. PCP ``n_prey``), ``render_mode`` (TaskEnv) and ``seed``, ``shard`` (vector envs).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from comat.config import SafetyConfig, SimConfig

__all__ = ["EnvOptions", "check_count"]


def check_count(name: str, value: Any) -> None:
    """ValueError naming ``name`` unless ``value`` is None or a positive integer (a bool is not)."""
    if value is not None and (isinstance(value, bool) or not isinstance(value, int) or value < 1):
        raise ValueError(f"{name} must be a positive integer, got {value!r}")


@dataclass(frozen=True)
class EnvOptions:
    """What an environment runs: its teams, physics, safety filter, step length and reality layer.

    Every field is optional; the values are checked here where they need no task (the counts),
    and where they are used otherwise (teams: :func:`comat.envs.base.team_source`; ``tier``:
    :class:`comat.config.SimConfig`; ``reality``: :func:`comat.reality.resolve_reality`).
    """

    coalitions: Any = "train"
    """A composition set (:data:`comat.team.COALITION_SETS`: "train", "val", "test", "scale",
    "size", "capability"), a YAML file, or a list of teams; each reset draws one uniformly."""
    team: Any = None
    """A fixed team (TeamSpec or dict) used at every reset instead."""
    tier: str = "wheels"
    """"wheels" or "unicycle"; ``sim`` instead gives a full SimConfig."""
    sim: SimConfig | None = None
    """Physics settings (None: the defaults of ``tier``)."""
    safety: SafetyConfig | None = None
    """Settings of the barrier filter (None: the defaults)."""
    ticks_per_step: int | None = None
    """Control ticks per env step (None: the task's, PCP 29, HMT 74)."""
    max_robots: int | None = None
    """Robot slots per environment (None: the largest team it may get)."""
    state_robots: int | None = None
    """Robots covered by the centralized state (None: a PettingZoo env covers its robot slots, at
    least 8, so every set has a ``state()``; a vector env covers 8, the baselines' size)."""
    reality: Any = "off"
    """The reality layer: "off" (the ideal world), "nominal", "stress", a profile file, a
    :class:`comat.reality.RealityConfig` or a mapping of its fields."""

    def __post_init__(self) -> None:
        check_count("ticks_per_step", self.ticks_per_step)
        check_count("state_robots", self.state_robots)

    @classmethod
    def names(cls) -> tuple[str, ...]:
        """The options' names, in declaration order."""
        return tuple(f.name for f in dataclasses.fields(cls))

    @classmethod
    def split(cls, options: Mapping[str, Any]) -> tuple[EnvOptions, dict[str, Any]]:
        """(EnvOptions of the keys it has, every other key and value) of ``options``."""
        names = set(cls.names())
        mine = {k: v for k, v in options.items() if k in names}
        return cls(**mine), {k: v for k, v in options.items() if k not in names}

    @classmethod
    def of(cls, options: Mapping[str, Any], owner: str) -> EnvOptions:
        """EnvOptions of ``options``; a TypeError naming ``owner`` and the valid names for any other key."""
        opts, rest = cls.split(options)
        if rest:
            valid = sorted(cls.names())
            raise TypeError(f"{owner} got unknown option(s) {sorted(rest)}; valid options: {valid}")
        return opts

    def sim_config(self) -> SimConfig:
        """``sim``, or the default SimConfig of ``tier``."""
        return self.sim or SimConfig(tier=self.tier)
