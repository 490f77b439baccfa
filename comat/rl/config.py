"""Run configuration: presets (``comat/data/presets/*.yaml``, also seen as ``train/configs/``) resolved
for one algo, task and seed.

A preset holds values only, for every algorithm at once::

    total_env_steps, seeds, tier, eval_every_steps, eval_episodes_per_team,
    checkpoint_every_steps, env_workers, torch_threads, ppo: {PPOConfig}, qmix: {QmixConfig},
    models: {LEARNER: {its model config}, ...}   (the registered learners: comat.learners)
    reality: off | nominal | stress | PROFILE.yaml | {RealityConfig fields}
    reality_draw: point | intervals   (with reality=PROFILE.yaml: its values, or its intervals per episode)
    coalitions: train | SET | TEAMS.yaml   (what the run trains on; default train, U_train)

``reality`` is the reality layer the run trains at (:mod:`comat.reality`; default ``off``): a
level name, or a mapping of fields (``{level: nominal, pose_delay_ticks: 2}``; without ``level``
the fields change ``off``). The dotted overrides reach it as ``reality=nominal``,
``reality.level=stress`` or ``reality.pose_delay_ticks=2``. With a fitted profile
(``reality=PROFILE.yaml``), ``reality_draw=intervals`` draws its identified parameters afresh every
episode from their intervals (calibrated randomization, :mod:`comat.reality.randomize`); the default
``point`` takes its values. The run records the profile's path and hash either way.

:func:`resolve` picks the sections the algorithm uses and gives a :class:`RunConfig`, which is
what a run writes next to its results (``config.yaml``) and stores in its checkpoints.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from comat.config import LOOPS, load
from comat.envs.base import resolve_coalitions
from comat.envs.outside import is_outside, make_outside_env
from comat.learners import FAMILIES, learner_entry, learner_names
from comat.reality import RealityConfig, resolve_reality
from comat.reality.config import read_profile
from comat.reality.randomize import DRAW_MODES, CalibratedReality, calibrated, profile_intervals, profile_sha256
from comat.rl.ppo import PPOConfig
from comat.rl.qmix import QmixConfig
from comat.tasks import env_id as task_env_id
from comat.tasks import task_names
from comat.team import COALITION_SETS

__all__ = [
    "PRESETS_DIR",
    "TASKS",
    "RunConfig",
    "apply_overrides",
    "load_preset",
    "preset_names",
    "resolve",
    "run_reality",
]

TASKS = tuple(sorted(task_names()))
TIERS = ("wheels", "unicycle")
PRESETS_DIR = Path(__file__).resolve().parents[1] / "data" / "presets"
"""The named presets. They ship inside the package (a wheel has no ``train/``); the checkout's
``train/configs`` is a link to this folder, so there is one copy to edit."""
TRAINER_CONFIGS = {"ppo": PPOConfig, "qmix": QmixConfig}
"""A learner family (:data:`comat.learners.FAMILIES`) -> its trainer's config, filled by the preset's
section of that name."""
_RUN_KEYS = (
    "total_env_steps",
    "eval_every_steps",
    "eval_episodes_per_team",
    "checkpoint_every_steps",
    "env_workers",
    "torch_threads",
    "physics_threads",
    "eval_sets",
    "keep_policies_at",
)
_PRESET_KEYS = (
    *_RUN_KEYS,
    *("seeds", "tier", "loop", "coalitions", *FAMILIES, "models", "reality", "base", "by_task"),
    *("reality_draw", "reality_profile"),
)
"""``reality_profile`` is set by ``reality=PROFILE.yaml`` (the file its fields came from)."""
_TASK_KEYS = tuple(k for k in _PRESET_KEYS if k not in ("base", "by_task", "seeds"))
"""What ``by_task: {hmt: {...}}`` may change for one task (the budget, the trainer, the models ...)."""


@dataclass(frozen=True)
class RunConfig:
    """Everything that defines a training run."""

    algo: str
    task: str
    seed: int
    tier: str
    total_env_steps: int
    """Stop after this many env steps (one env step = one step of one team)."""
    eval_every_steps: int
    """Evaluate on the training coalitions every this many env steps (and at the end)."""
    eval_episodes_per_team: int
    """Evaluation episodes per training coalition (deterministic actions); 0: no evaluation."""
    checkpoint_every_steps: int
    """Write the checkpoint every this many env steps (and at the end)."""
    trainer: PPOConfig | QmixConfig
    model: Any
    """The learner's model config (:meth:`comat.learners.LearnerEntry.config_class`)."""
    env_workers: int = 1
    """Processes stepping the environments (:class:`comat.envs.ShardedVectorEnv` when > 1).
    Part of the run's identity: results are exactly reproducible for the same value."""
    torch_threads: int = 2
    """``torch.set_num_threads`` for the learner (recorded: reductions depend on it)."""
    device: str = "cpu"
    """Where the update runs: ``"cpu"`` (in place) or ``"cuda"`` (a copy of the networks there,
    mirrored to the CPU ones that act; :mod:`comat.rl.device`). Part of the run's identity: GPU
    kernels round differently."""
    physics_threads: int = 1
    """Threads MuJoCo steps each environment process's teams on (:attr:`SimConfig.threads`;
    results do not depend on it). More than 1 pays with ``env_workers: 1`` on an otherwise
    idle machine: the learner's cores wait while the environments step."""
    reality: RealityConfig = dataclasses.field(default_factory=RealityConfig)
    """The reality layer of every environment the run builds, training and its periodic
    evaluation (:mod:`comat.reality`): each episode draws its own delays, noise, motors and
    start error from its seed (domain randomization). Default ``off``, the ideal world; a run
    config stored before the layer existed loads as ``off``."""
    loop: str = "comat"
    """What turns waypoints into wheel commands in every environment of the run
    (:attr:`comat.config.SafetyConfig.loop`): ``"comat"`` (comat's filter, the default) or an
    export's loop (``robotarium_v2``, ``shipped_v2`` ...), to train and evaluate against what the
    Robotarium will run. A run config stored before the option existed loads as ``comat``."""
    coalitions: Any = "train"
    """The teams the run trains on and its periodic evaluation plays: a set name
    (:data:`comat.team.COALITION_SETS`; ``train``, U_train, is the paper's protocol) or the teams
    themselves, a list of ``{robots: [...]}`` mappings, which :func:`resolve` reads from a
    YAML/JSON file (``coalitions=team.yaml`` trains one fixed team) so that the run's config.yaml
    holds them. A run config stored before the option existed loads as ``train``."""

    eval_sets: tuple[str, ...] = ()
    """Composition sets (:data:`comat.team.COALITION_SETS`) each periodic evaluation also plays, beside
    the training coalitions, into ``eval_<set>.csv`` (the same episodes per coalition): budget curves
    on the validation and unseen sets. Default none; a run config stored before the option loads so."""
    keep_policies_at: tuple[int, ...] = ()
    """Env steps at which the run also keeps its policy as ``policy_<steps>.pt`` (at the first update
    that reaches each), e.g. the candidates of a checkpoint rule chosen on the validation set.
    Default none; a run config stored before the option loads so."""
    reality_draw: Any = "point"
    """How the run takes a fitted profile (``reality=PROFILE.yaml``): ``"point"`` (its values, the
    default; stored as ``{mode: point, profile, sha256}`` when the run has a profile) or
    ``{mode: intervals, profile, sha256, intervals: {name: [lo, hi]}}``, its identified parameters
    drawn every episode from their intervals (:mod:`comat.reality.randomize`; written by
    ``reality_draw=intervals``). A run config stored before the option existed loads as ``point``."""

    def __post_init__(self) -> None:
        if not isinstance(self.reality, RealityConfig):
            object.__setattr__(self, "reality", run_reality(self.reality))
        object.__setattr__(self, "eval_sets", _eval_sets(self.eval_sets))
        object.__setattr__(self, "keep_policies_at", _keep_at(self.keep_policies_at, self.total_env_steps))
        _check_choice("loop", self.loop, LOOPS)
        draw = self.reality_draw
        if draw == "point":
            return
        if not isinstance(draw, Mapping) or draw.get("mode") not in DRAW_MODES:
            raise ValueError(f"reality_draw must be one of {list(DRAW_MODES)} or a stored record of one, got {draw!r}")
        if draw["mode"] == "intervals" and not isinstance(self.reality, CalibratedReality):
            try:
                intervals = {k: (lo, hi) for k, (lo, hi) in dict(draw["intervals"]).items()}
                object.__setattr__(
                    self, "reality", calibrated(self.reality, intervals, draw["profile"], draw["sha256"])
                )
            except (KeyError, TypeError) as err:
                raise ValueError(
                    f"reality_draw must record mode, profile, sha256 and intervals {{name: [lo, hi]}}, got {draw!r}"
                ) from err

    @property
    def overlap(self) -> bool:
        """Whether the next rollout is collected beside each update (``ppo.overlap``; QMIX has none)."""
        return bool(getattr(self.trainer, "overlap", False))

    @property
    def env_id(self) -> str:
        return self.task if is_outside(self.task) else task_env_id(self.task)

    def to_dict(self) -> dict[str, Any]:
        out = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        out["trainer"], out["model"] = dataclasses.asdict(self.trainer), dataclasses.asdict(self.model)
        # every field resolved: later level changes do not reach it (a calibrated run: the profile's
        # point values, its draws in reality_draw)
        out["reality"] = dataclasses.asdict(getattr(self.reality, "point", self.reality))
        for key in ("eval_sets", "keep_policies_at"):  # unset: a run's config as before the options
            if out[key]:
                out[key] = list(out[key])
            else:
                del out[key]
        if isinstance(self.reality, CalibratedReality):
            out["reality_draw"] = self.reality.record()
        elif out["reality_draw"] == "point":  # no profile: a run's config as before the option
            del out["reality_draw"]
        return out

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> RunConfig:
        data = dict(data)
        entry = learner_entry(data.get("algo"))
        data["trainer"] = load(TRAINER_CONFIGS[entry.family], data.get("trainer"), prefix="trainer")
        data["model"] = load(entry.config_class(), data.get("model"), prefix="model")
        data["reality"] = run_reality(data.get("reality"))  # absent (a run from before the layer): off
        return cls(**data)


def _eval_sets(value: Any) -> tuple[str, ...]:
    """``eval_sets`` as a tuple of distinct set names (ValueError naming the key otherwise)."""
    names = (value,) if isinstance(value, str) else value
    if (
        not isinstance(names, (list, tuple))
        or any(n not in COALITION_SETS for n in names)
        or len(set(names)) != len(names)
    ):
        raise ValueError(f"eval_sets must be a list of distinct names from {list(COALITION_SETS)}, got {value!r}")
    return tuple(names)


def _keep_at(value: Any, total: int) -> tuple[int, ...]:
    """``keep_policies_at`` as sorted distinct env steps in [1, ``total``] (ValueError otherwise)."""
    steps = (value,) if isinstance(value, int) and not isinstance(value, bool) else value
    if (
        not isinstance(steps, (list, tuple))
        or any(isinstance(t, bool) or not isinstance(t, int) or not 1 <= t <= total for t in steps)
        or len(set(steps)) != len(steps)
    ):
        raise ValueError(
            f"keep_policies_at must be a list of distinct env steps between 1 and total_env_steps ({total:,}), "
            f"got {value!r}"
        )
    return tuple(sorted(steps))


def run_reality(value: Any) -> RealityConfig:
    """A run's reality layer from what a preset, an override or a stored config holds (see
    :func:`comat.reality.resolve_reality`); errors name the key as the overrides spell it
    (``reality.pose_delay_ticks must be an integer >= 0 (ticks), got -1``)."""
    try:
        return resolve_reality(value, "reality")
    except (TypeError, ValueError) as err:
        text = str(err)
        if text.startswith("RealityConfig."):
            raise type(err)("reality." + text[len("RealityConfig.") :]) from err
        raise


def run_draw(value: Any, profile: Any) -> str | dict[str, Any]:
    """A run's ``reality_draw`` from a preset's or an override's ``point | intervals`` and the
    profile ``reality=PROFILE.yaml`` named (None: none): ``"point"`` without a profile, else the
    record of the profile's path, hash and (``intervals``) its intervals (:func:`profile_intervals`)."""
    if value not in DRAW_MODES:
        raise ValueError(f"reality_draw must be one of {list(DRAW_MODES)}, got {value!r}")
    if profile is None:
        if value == "intervals":
            raise ValueError(
                "reality_draw=intervals draws from a fitted profile's intervals: it needs reality=PROFILE.yaml "
                "(comat calibrate --out), got no profile"
            )
        return "point"
    record = {"mode": value, "profile": str(profile), "sha256": profile_sha256(profile)}
    if value == "intervals":
        intervals = profile_intervals(str(profile), "reality_draw")
        if not intervals:
            raise ValueError(f"reality_draw: profile {str(profile)!r} has no interval to draw from, got none")
        record["intervals"] = {k: [lo, hi] for k, (lo, hi) in intervals.items()}
    return record


def run_coalitions(value: Any, task: str) -> str | list[dict[str, Any]]:
    """A set name as it is; a file or a list of teams as the checked teams, stored as mappings."""
    if isinstance(value, str) and value in COALITION_SETS:
        return value
    try:
        teams = resolve_coalitions(value, task)
    except (TypeError, ValueError) as err:
        raise ValueError(f"coalitions: {err}") from err
    return [t.to_dict() for t in teams]


def _check_outside(preset: dict[str, Any], entry, task: str) -> None:
    """One-line ValueError where ``task``, an outside env (:mod:`comat.envs.outside`), cannot run as
    ``preset`` asks: a learner that reads poses or capabilities, an env that does not build, or a
    setting of comat's own world (coalitions, reality, loop)."""
    if not entry.outside_envs:
        raise ValueError(
            f"algo {entry.name!r} cannot train on outside task {task!r}: it reads robot poses or capabilities at "
            f"fixed places of comat's observation, which an outside env does not have; learners that can: "
            f"{[n for n in learner_names() if learner_entry(n).outside_envs]}"
        )
    make_outside_env(task).close()  # an unknown env, or one comat cannot drive, said in one line now
    for key, default in (("coalitions", "train"), ("loop", "comat")):
        if preset.get(key, default) != default:
            raise ValueError(f"{key}: outside task {task!r} has its own team and world, got {preset[key]!r}")
    label = run_reality(preset.get("reality")).label
    if label != "off":
        raise ValueError(f"reality: outside task {task!r} has no reality layer (comat's world only), got {label!r}")


def _check_choice(name: str, value: Any, choices: tuple[str, ...]) -> None:
    if value not in choices:
        raise ValueError(f"{name} must be one of {list(choices)}, got {value!r}")


def preset_names() -> list[str]:
    return sorted(p.stem for p in PRESETS_DIR.glob("*.yaml"))


def load_preset(preset: str | Path, _seen: tuple[str, ...] = ()) -> dict[str, Any]:
    """A preset by name (``<name>.yaml`` in :data:`PRESETS_DIR`) or path, checked for unknown keys.

    A preset may name another as ``base: NAME`` (a name or a path): it is the base's settings with
    this file's keys changed (sections merged key by key)."""
    import yaml

    path = Path(preset)
    if path.suffix not in (".yaml", ".yml"):
        path = PRESETS_DIR / f"{preset}.yaml"
        if not path.is_file():
            raise ValueError(f"unknown preset {str(preset)!r}; presets: {preset_names()} (or a path to a YAML file)")
    elif not path.is_file():
        raise ValueError(f"preset file {str(path)!r} does not exist")
    try:
        with open(path) as fh:
            data = yaml.safe_load(fh)
    except yaml.YAMLError as err:
        where = getattr(err, "problem_mark", None)
        at = f" at line {where.line + 1}, column {where.column + 1}" if where is not None else ""
        raise ValueError(f"preset {str(path)!r} is not valid YAML{at}: {getattr(err, 'problem', None) or err}") from err
    except UnicodeDecodeError as err:
        raise ValueError(f"preset {str(path)!r} is not a text (YAML) file: {err.reason}") from err
    if data is None:
        # An empty file would silently mean every default, e.g. a 4,000,000-step run.
        raise ValueError(f"preset {str(path)!r} is empty; expected a mapping of settings (see {PRESETS_DIR}/*.yaml)")
    if not isinstance(data, dict):
        raise TypeError(f"preset {str(path)!r} must be a mapping of settings, got {type(data).__name__}")
    _check_preset_keys(data, f"preset {str(path)!r}")
    data = _reality_as_mapping(data)
    if "base" in data:
        base = data.pop("base")
        if str(path.resolve()) in _seen:
            raise ValueError(f"preset {str(path)!r}: its base presets form a cycle")
        if not isinstance(base, str):
            raise TypeError(f"preset {str(path)!r}: base must be a preset name or path, got {base!r}")
        if base.endswith((".yaml", ".yml")) and not Path(base).is_absolute():
            base = str(path.parent / base)  # relative to this file
        data = _merge(load_preset(base, (*_seen, str(path.resolve()))), data)
    return data


def _check_preset_keys(data: dict[str, Any], source: str) -> None:
    unknown = sorted(set(data) - set(_PRESET_KEYS))
    if unknown:
        raise ValueError(f"unknown key(s) {unknown} in {source}; valid keys: {sorted(_PRESET_KEYS)}")
    models = data.get("models") or {}
    unknown = sorted(set(models) - set(learner_names()))
    if unknown:
        raise ValueError(f"unknown algo(s) {unknown} under models in {source}; valid: {list(learner_names())}")
    by_task = data.get("by_task")
    if by_task is not None:
        if not isinstance(by_task, Mapping) or not set(by_task) <= set(TASKS):
            raise ValueError(f"by_task in {source} must map task names {list(TASKS)} to settings, got {by_task!r}")
        for task, entry in by_task.items():
            if not isinstance(entry, Mapping) or not set(entry) <= set(_TASK_KEYS):
                raise ValueError(f"by_task.{task} in {source} must be a mapping of {sorted(_TASK_KEYS)}, got {entry!r}")


def _reality_as_mapping(data: dict[str, Any]) -> dict[str, Any]:
    """``data`` with a level name under ``reality`` written as ``{level: name}``, so merging a
    preset, its base and the overrides changes the layer field by field (OmegaConf would let a
    later name replace earlier fields, or fields replace a name, without a word)."""
    value = data.get("reality")
    if value is None or isinstance(value, Mapping):
        return data
    if isinstance(value, str) and value.endswith((".yaml", ".yml")):  # a calibrated profile: its fields
        return {**data, "reality": read_profile(value), "reality_profile": value}
    return {**data, "reality": {"level": value}}


def _merge(base: dict[str, Any], changes: dict[str, Any]) -> dict[str, Any]:
    """``base`` with ``changes`` applied, mappings merged key by key (OmegaConf's merge)."""
    from omegaconf import OmegaConf

    return OmegaConf.to_container(OmegaConf.merge(OmegaConf.create(base), OmegaConf.create(changes)))


def apply_overrides(preset: dict[str, Any], overrides: list[str] | tuple[str, ...]) -> dict[str, Any]:
    """The preset with dotted ``key=value`` overrides (``ppo.lr=3e-4 models.comat.heads=8``), parsed
    by OmegaConf's dotlist grammar; the result is checked like a preset (and typed when resolved)."""
    from omegaconf import OmegaConf
    from omegaconf.errors import OmegaConfBaseException

    if not overrides:
        return preset
    bad = [o for o in overrides if not isinstance(o, str) or "=" not in o or o.startswith("=")]
    if bad:
        raise ValueError(f"overrides must be key=value (e.g. ppo.lr=3e-4 models.comat.heads=8), got {bad}")
    try:
        # One at a time: `reality=nominal reality.pose_delay_ticks=2` is the nominal level with one
        # field changed, whatever the order (one dotlist would let the later replace the earlier).
        changes = {}
        for o in overrides:
            changes = _merge(changes, _reality_as_mapping(OmegaConf.to_container(OmegaConf.from_dotlist([o]))))
    except OmegaConfBaseException as err:
        raise ValueError(f"overrides {list(overrides)} could not be parsed: {str(err).splitlines()[0]}") from err
    _check_preset_keys(changes, f"overrides {list(overrides)}")
    merged = _merge(_reality_as_mapping(preset), changes)
    if merged.get("by_task"):  # an override beats the preset's per-task value of the same key
        for entry in merged["by_task"].values():
            _drop_keys(entry, changes)
    return merged


def _drop_keys(entry: dict[str, Any], changes: dict[str, Any]) -> None:
    """Remove from ``entry`` every leaf that ``changes`` sets (nested mappings walked together)."""
    for key, value in changes.items():
        if key not in entry:
            continue
        if isinstance(value, Mapping) and isinstance(entry[key], Mapping):
            _drop_keys(entry[key], value)
        else:
            del entry[key]


def for_task(preset: dict[str, Any], task: str) -> dict[str, Any]:
    """The preset as ``task`` runs it: its ``by_task[task]`` settings merged in (key by key)."""
    by_task = preset.get("by_task") or {}
    rest = {k: v for k, v in preset.items() if k != "by_task"}
    return _merge(rest, by_task[task]) if by_task.get(task) else rest


def resolve(
    preset: dict[str, Any],
    algo: str,
    task: str,
    seed: int | None = None,
    tier: str | None = None,
    total_env_steps: int | None = None,
    env_workers: int | None = None,
    device: str | None = None,
) -> RunConfig:
    """The run config of ``algo`` on ``task`` from a preset; explicit arguments override it
    (``device``: "cpu" or "cuda", as :func:`comat.rl.device.resolve_device` gives)."""
    entry = learner_entry(algo)
    if is_outside(task):
        _check_outside(preset, entry, task)
    else:
        _check_choice("task", task, TASKS)
    preset = for_task(preset, task)
    tier = tier or preset.get("tier", "unicycle")
    _check_choice("tier", tier, TIERS)
    if seed is None:
        seed = (preset.get("seeds") or [0])[0]
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
    run = {k: preset[k] for k in _RUN_KEYS if k in preset}
    if total_env_steps is not None:
        run["total_env_steps"] = total_env_steps
    if env_workers is not None:
        run["env_workers"] = env_workers
    defaults = {
        "total_env_steps": 4_000_000,
        "eval_every_steps": 200_000,
        "eval_episodes_per_team": 1,
        "checkpoint_every_steps": 100_000,
        "env_workers": 1,
        "torch_threads": 2,
        "physics_threads": 1,
    }
    for key, default in defaults.items():
        value = run.setdefault(key, default)
        least = 0 if key == "eval_episodes_per_team" else 1
        if isinstance(value, bool) or not isinstance(value, int) or value < least:
            raise ValueError(f"{key} must be an integer >= {least}, got {value!r}")
    if is_outside(task):  # an outside env steps in the learner's process (comat.envs.outside)
        run["env_workers"] = 1
    if device is not None:
        _check_choice("device", device, ("cpu", "cuda"))
        run["device"] = device
    section = entry.family
    try:
        return RunConfig.from_dict(
            {
                "algo": algo,
                "task": task,
                "seed": seed,
                "tier": tier,
                **run,
                "trainer": preset.get(section),
                "model": (preset.get("models") or {}).get(algo),
                "reality": preset.get("reality"),
                "reality_draw": run_draw(preset.get("reality_draw", "point"), preset.get("reality_profile")),
                "loop": preset.get("loop", "comat"),
                "coalitions": "own" if is_outside(task) else run_coalitions(preset.get("coalitions", "train"), task),
            }
        )
    except (TypeError, ValueError) as err:  # name the key as presets and overrides spell it
        text = str(err)
        for stored, spelled in (("trainer", section), ("model", f"models.{algo}")):
            if text.startswith(stored + "."):
                raise type(err)(spelled + text[len(stored) :]) from err
            if f" for {stored};" in text or text.startswith(f"{stored} must be"):
                raise type(err)(
                    text.replace(f" for {stored};", f" for {spelled};").replace(
                        f"{stored} must be", f"{spelled} must be", 1
                    )
                ) from err
        raise
