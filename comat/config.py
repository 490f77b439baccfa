"""Frozen config dataclasses (one schema per concern) and YAML loading that rejects unknown keys.

Every field has a docstring; YAML presets hold values only. ``load(cls, mapping)`` builds a
config from a dict, raising on unknown keys with the list of valid ones, and on wrongly typed
values; ``to_dict`` gives the resolved config that every run writes next to its results.
"""

from __future__ import annotations

import dataclasses
import math
import types
import typing
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

from comat import constants as C
from comat.mjcf.robot import TIERS
from comat.mjcf.scene import DEFAULT_SUBSTEPS

__all__ = ["LOOPS", "REFERENCE_TIER", "SafetyConfig", "SimConfig", "load", "load_yaml", "to_dict"]

REFERENCE_TIER = "unicycle"
"""Tier of a policy that has no training tier (the reference policies): the presets' training tier,
so reference numbers sit next to a checkpoint's evaluated in the same dynamics."""

T = TypeVar("T")


@dataclass(frozen=True)
class SimConfig:
    """MuJoCo world settings for one dynamics tier."""

    tier: str = "wheels"
    """``"wheels"`` (free chassis on friction-driven wheels) or ``"unicycle"`` (planar joints)."""
    substeps: int | None = None
    """Physics steps per 0.033 s control tick; None = the tier's default (docs/physics.md)."""
    timestep_s: float | None = None
    """Alternative to ``substeps``: the physics timestep, which must divide the 0.033 s tick."""
    profile: str = C.DEFAULT_PROFILE.name
    """Robot generation: ``"gritsbot"`` (axle 0.105 m) or ``"gternal"`` (axle 0.11 m)."""
    threads: int = 1
    """Threads MuJoCo's batch steps many teams on (1: the calling thread only). Results do not
    depend on it: each team's simulation is independent."""

    def __post_init__(self) -> None:

        if self.tier not in TIERS:
            raise ValueError(f"SimConfig.tier must be one of {TIERS}, got {self.tier!r}")
        if self.profile not in C.PROFILES:
            raise ValueError(f"SimConfig.profile must be one of {sorted(C.PROFILES)}, got {self.profile!r}")
        if isinstance(self.threads, bool) or not isinstance(self.threads, int) or self.threads < 1:
            raise ValueError(f"SimConfig.threads must be a positive integer, got {self.threads!r}")
        if self.substeps is not None and (
            isinstance(self.substeps, bool) or not isinstance(self.substeps, int) or self.substeps < 1
        ):
            raise ValueError(f"SimConfig.substeps must be a positive integer, got {self.substeps!r}")
        if self.timestep_s is not None:
            if self.substeps is not None:
                raise ValueError(
                    f"SimConfig takes substeps or timestep_s, not both (got substeps={self.substeps}, "
                    f"timestep_s={self.timestep_s})"
                )
            ratio = C.CONTROL_DT_S / self.timestep_s if self.timestep_s > 0 else float("nan")
            if not (math.isfinite(ratio) and ratio >= 1 and abs(ratio - round(ratio)) < 1e-9 * ratio):
                raise ValueError(
                    f"SimConfig.timestep_s must divide the {C.CONTROL_DT_S} s control tick "
                    f"(e.g. {C.CONTROL_DT_S / 4:.6g} = tick/4), got {self.timestep_s!r} "
                    f"(tick/timestep = {ratio:.6g})"
                )

    @property
    def resolved_substeps(self) -> int:
        """Physics steps per tick after defaults."""

        if self.timestep_s is not None:
            return round(C.CONTROL_DT_S / self.timestep_s)
        return self.substeps if self.substeps is not None else DEFAULT_SUBSTEPS[self.tier]


LOOPS = ("comat", "robotarium_v2", "robotarium_legacy", "shipped_v2", "shipped_legacy")
"""The per-tick loops :class:`SafetyConfig` can run (``loop``): comat's filter, or an export's
main.py under an rps generation, with the Robotarium's barrier or with comat's shipped filter."""


@dataclass(frozen=True)
class SafetyConfig:
    """Control-barrier-function filter settings (DESIGN §4, docs/safety.md)."""

    safety_distance_m: float = C.SAFETY_DISTANCE_M
    """Minimum distance d_s kept between the robots' projected points."""
    projection_distance_m: float = C.PROJECTION_DISTANCE_M
    """How far ahead of the axle the barrier's point sits."""
    boundary_margin_m: float = C.BOUNDARY_MARGIN_M
    """Projected points stay this far inside the arena."""
    barrier_gain: float = 10.0
    """γ (1/s) of the pair rows ḣ >= -γ·h, h = ‖p_i - p_j‖² - d_s²; γ·0.033 s < 1 keeps the
    zero-order-hold tick safe."""
    boundary_gain: float = 10.0
    """γ (1/s) of the boundary rows."""
    wheel_speed_fraction: float = 0.999
    """Fraction of the 12.5 rad/s wheel limit the filtered command may use, so solver
    tolerance never produces a Robotarium actuator error."""
    eps: float = 1e-3
    """OSQP absolute and relative tolerance of the ADMM iterations. Polishing then solves the
    KKT system of the detected active set, so a polished answer is exact to ~1e-12; the rare
    unpolished answer is repaired or re-solved 1000x tighter (comat.safety.filter)."""
    max_iter: int = 4000
    """OSQP iteration limit; reaching it triggers the fallback."""
    admm_rho: float = 0.1
    """OSQP's initial ADMM step size ρ (OSQP's own default). Under a reality layer the robust
    filter takes :data:`comat.reality.margin.ROBUST_ADMM_RHO` instead, unless this is set."""
    feasibility_tol: float = 1e-4
    """A solution violating any row by more than this (m/s, or m²/s for pair rows) is rejected."""
    strict: bool = False
    """Raise :class:`comat.safety.InfeasibleError` instead of braking when a team's QP fails."""
    robust: bool = True
    """Under a reality layer (``reality=`` not ``off``), lower the gains to the loop delay's
    bound, widen the distances by the measurement bound and dead-reckon repeated poses
    (:mod:`comat.reality.margin`); False keeps these settings as given. No effect at ``off``."""
    loop: str = "comat"
    """Which loop turns waypoints into wheel commands every tick: ``"comat"`` (comat's own
    filter, the settings above) or the loop an export runs on the Robotarium
    (:mod:`comat.safety.deployed`): ``"robotarium_v2"`` / ``"robotarium_legacy"``, the exported
    main.py with that rps generation's own barrier and speed cap, or ``"shipped_v2"`` /
    ``"shipped_legacy"``, main.py with comat's filter in the barrier's place
    (:class:`comat.safety.deployed.ShippedFilter`, made robust to the reality layer as comat's
    own is). The Robotarium loops ignore every other field here."""

    def __post_init__(self) -> None:
        for name in ("safety_distance_m", "projection_distance_m", "barrier_gain", "boundary_gain", "eps", "admm_rho"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f"SafetyConfig.{name} must be a positive finite number, got {value!r}")
        if not 0 <= self.boundary_margin_m < 0.9:
            raise ValueError(f"SafetyConfig.boundary_margin_m must be in [0, 0.9) m, got {self.boundary_margin_m!r}")
        if not 0 < self.wheel_speed_fraction <= 1:
            raise ValueError(f"SafetyConfig.wheel_speed_fraction must be in (0, 1], got {self.wheel_speed_fraction!r}")
        if self.loop not in LOOPS:
            raise ValueError(f"SafetyConfig.loop must be one of {list(LOOPS)}, got {self.loop!r}")
        if self.barrier_gain * C.CONTROL_DT_S >= 1 or self.boundary_gain * C.CONTROL_DT_S >= 1:
            raise ValueError(
                f"SafetyConfig gains must satisfy gain * {C.CONTROL_DT_S} s < 1 to stay safe between ticks, "
                f"got barrier_gain={self.barrier_gain}, boundary_gain={self.boundary_gain}"
            )


def check_numbers(config: Any, section: str, **rules: tuple[str, ...]) -> None:
    """Raise ValueError naming ``section.field``, the expected range and the value, for fields
    outside their range. Rules (each a tuple of field names): ``positive`` (finite > 0),
    ``non_negative`` (finite >= 0), ``at_least_one`` (>= 1), ``unit`` (in [0, 1]), ``discount``
    (in (0, 1])."""
    tests = {
        "positive": (lambda v: math.isfinite(v) and v > 0, "a finite number > 0"),
        "non_negative": (lambda v: math.isfinite(v) and v >= 0, "a finite number >= 0"),
        "at_least_one": (lambda v: v >= 1, "an integer >= 1"),
        "unit": (lambda v: 0 <= v <= 1, "a number in [0, 1]"),
        "discount": (lambda v: 0 < v <= 1, "a number in (0, 1]"),
    }
    for rule, names in rules.items():
        ok, expected = tests[rule]
        for name in names:
            value = getattr(config, name)
            if value is None:
                continue
            if not ok(float(value)):
                raise ValueError(f"{section}.{name} must be {expected}, got {value!r}")


def _check_type(owner: str, name: str, hint: Any, value: Any) -> Any:
    origin = typing.get_origin(hint)
    options = typing.get_args(hint) if origin in (typing.Union, types.UnionType) else (hint,)
    for opt in options:
        if opt is type(None) and value is None:
            return value
        if opt is float and isinstance(value, (int, float)) and not isinstance(value, bool):
            return float(value)
        if opt in (int, str, bool) and type(value) is opt:
            return value
        if dataclasses.is_dataclass(opt) and isinstance(value, dict):
            return load(opt, value, prefix=f"{owner}.{name}")
    expected = " or ".join(getattr(o, "__name__", str(o)) for o in options)
    raise TypeError(f"{owner}.{name} must be {expected}, got {value!r} ({type(value).__name__})")


def load(cls: type[T], mapping: dict[str, Any] | None, prefix: str | None = None) -> T:
    """Build ``cls`` from a mapping; unknown keys and wrong types raise with the valid choices."""
    owner = prefix or cls.__name__
    mapping = {} if mapping is None else mapping
    if not isinstance(mapping, dict):
        raise TypeError(f"{owner} must be a mapping, got {type(mapping).__name__}")
    fields = {f.name: f for f in dataclasses.fields(cls)}
    unknown = sorted(set(mapping) - set(fields))
    if unknown:
        raise ValueError(f"unknown key(s) {unknown} for {owner}; valid keys: {sorted(fields)}")
    hints = typing.get_type_hints(cls)
    kwargs = {k: _check_type(owner, k, hints[k], v) for k, v in mapping.items()}
    return cls(**kwargs)


def load_yaml(cls: type[T], path: str | Path) -> T:
    """Load ``cls`` from a YAML file of values (see :func:`load`)."""
    import yaml

    with open(path) as fh:
        data = yaml.safe_load(fh)
    return load(cls, data, prefix=f"{cls.__name__} ({path})")


def to_dict(config: Any) -> dict[str, Any]:
    """The resolved config as plain data (for YAML/JSON next to results)."""
    return dataclasses.asdict(config)
