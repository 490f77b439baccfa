"""The learners: the one list of registered learners that every command, preset, figure, table,
benchmark and policy file reads. It imports no torch (``comat --help`` and the reports load it).

A learner is a network module (``comat/models/<name>.py``: its config dataclass, its ``nn.Module``
and a ``build(dims, config, acting_only)`` function beside them) and one :class:`LearnerEntry` here
that names them by import string, so nothing is imported until a learner is built. Callers ask the
entry (``learner_entry(algo).family``, ``.team_sized`` ...) and never compare a learner's name.

=========  =====================  ======  =========  ==========  ==========  ==============  =======  =============
name       label                  family  acts with  uses state  team-sized  autoregressive  exports  outside envs
=========  =====================  ======  =========  ==========  ==========  ==============  =======  =============
ippo       IPPO (team advantage)  ppo     policy     no          no          no              no       yes
mappo      MAPPO                  ppo     policy     yes         yes         no              no       yes
qmix       QMIX                   qmix    agents     no          yes         no              no       yes
mat        MAT                    ppo     policy     no          yes         yes             no       yes
cash-caps  CASH-caps              ppo     policy     no          no          no              no       no
cash       CASH                   ppo     policy     no          no          no              no       no
comat      COMAT                  ppo     policy     no          no          yes             yes      no
=========  =====================  ======  =========  ==========  ==========  ==============  =======  =============

:func:`learner_names` is the order commands and tables list them in (the paper's: baselines from
the least to the most team-aware, COMAT last); :func:`learner_entry` turns a name into its entry
with a one-line error for a name that is not registered. A learner of one's own registers through
:func:`register_learner`, the ``COMAT_LEARNERS`` environment variable or a ``comat.learners`` entry
point (docs/write-a-learner.md); its runs, policy files and reports then work as the built-in ones'.
"""

from __future__ import annotations

import importlib
import os
import re
from dataclasses import dataclass
from importlib.metadata import entry_points
from typing import Any

__all__ = [
    "FAMILIES",
    "PLUGIN_ENV",
    "LearnerEntry",
    "learner_entry",
    "learner_names",
    "load_plugins",
    "not_registered",
    "plugin_error",
    "register_learner",
]

FAMILIES = {"ppo": ("policy",), "qmix": ("agents",)}
"""How a learner learns -> the modules it acts with. ``ppo`` (:class:`comat.rl.ppo.PPOTrainer`, the
preset's ``ppo:`` section): ``build`` returns ``{"policy": module}`` whose ``act(obs, mask, state,
deterministic, generator)`` gives actions, log-probabilities and values and ``evaluate_actions(obs,
mask, actions, state)`` log-probabilities, entropy and values. ``qmix``
(:class:`comat.rl.qmix.QmixTrainer`, the ``qmix:`` section): ``{"agents": Q-networks, "mixer":
mixer}``; it acts greedily on the agents' Q-values."""

PLUGIN_ENV = "COMAT_LEARNERS"
"""Environment variable naming learners of one's own to register on import: ``module:ENTRY``
entries (a :class:`LearnerEntry` object in that module, the module on ``PYTHONPATH``),
comma-separated. Installed packages declare theirs as entry points of the group ``comat.learners``."""

_NAME = re.compile(r"^[a-z][a-z0-9]*(-[a-z0-9]+)*$")
_COLOUR = re.compile(r"^#[0-9a-fA-F]{6}$")
_TARGET = re.compile(r"^[A-Za-z_][\w.]*:[A-Za-z_]\w*$")


@dataclass(frozen=True)
class LearnerEntry:
    """What names a learner and what the code asks of it (see the module docstring's table)."""

    name: str
    """Its name on the command line, in presets (``models: {name: ...}``), run folders and files:
    lower-case letters and digits, words joined by ``-`` (``cash-caps``)."""
    label: str
    """How tables and figures name it (``"MAPPO"``)."""
    colour: str
    """Its colour in every figure (``"#2ca02c"``), its own: colour means learner."""
    family: str
    """How it learns, one of :data:`FAMILIES`."""
    config: str
    """Import string of its model config dataclass (``"comat.models.mat:MatConfig"``): the preset's
    ``models.<name>`` block fills it; frozen, with a default for every field."""
    builder: str
    """Import string of ``build(dims, config, acting_only=False) -> {module name: nn.Module}``:
    freshly initialised networks for the sizes ``dims`` (:class:`comat.rl.algos.Dims`: ``obs_dim``,
    ``n_types``, ``n_caps``, ``state_dim`` and ``layout``); ``acting_only``: only what deterministic
    acting needs (:attr:`acts_with`; a policy file keeps exactly those weights)."""
    uses_state: bool = False
    """The PPO trainer hands ``act`` and ``evaluate_actions`` the environment's global state
    (MAPPO's centralized critic). Deterministic acting never needs it. QMIX's mixer reads the state
    whatever this says."""
    team_sized: bool = False
    """Its networks have a fixed number of robot slots, its model config's ``max_robots``: its
    environments pad every team to them and a larger team is refused. Otherwise it plays any team
    size (U_scale's 20 robots) with no setting."""
    autoregressive: bool = False
    """It decodes the team's actions robot after robot (``act`` with cached keys and values,
    ``act_uncached`` the reference it must equal)."""
    exports: bool = False
    """``comat export`` ships it: sim2real/runtime.py has its numpy forward pass."""
    keeps: str = ""
    """What its policy file keeps to act, in words (docs/policies.md's table)."""
    outside_envs: bool = False
    """It reads a robot's observation as one vector plus the type one-hot, nothing at fixed places in
    it (no pose, no capabilities), so it trains on an outside PettingZoo env (:mod:`comat.envs.outside`,
    ``--task outside:MODULE``); a learner that reads poses or capabilities is refused there."""

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not _NAME.match(self.name):
            raise ValueError(
                f"LearnerEntry.name must be lower-case letters and digits, words joined by '-' (e.g. 'cash-caps'), "
                f"got {self.name!r}"
            )
        for key in ("label", "config", "builder", "keeps"):
            if not isinstance(getattr(self, key), str):
                raise TypeError(f"learner {self.name!r}: {key} must be a str, got {getattr(self, key)!r}")
        if not self.label:
            raise ValueError(f"learner {self.name!r}: label must be a non-empty str, got ''")
        if not isinstance(self.colour, str) or not _COLOUR.match(self.colour):
            raise ValueError(f"learner {self.name!r}: colour must be '#rrggbb', got {self.colour!r}")
        if self.family not in FAMILIES:
            raise ValueError(f"learner {self.name!r}: family must be one of {list(FAMILIES)}, got {self.family!r}")
        for key in ("config", "builder"):
            value = getattr(self, key)
            if not _TARGET.match(value):
                raise ValueError(f"learner {self.name!r}: {key} must be 'module:attribute', got {value!r}")
        for key in ("uses_state", "team_sized", "autoregressive", "exports", "outside_envs"):
            if not isinstance(getattr(self, key), bool):
                raise TypeError(f"learner {self.name!r}: {key} must be True or False, got {getattr(self, key)!r}")

    @property
    def acts_with(self) -> tuple[str, ...]:
        """The modules deterministic acting needs (:data:`FAMILIES`), what a policy file keeps."""
        return FAMILIES[self.family]

    @property
    def samples(self) -> bool:
        """It has a stochastic policy to sample actions from (QMIX acts greedily)."""
        return self.family == "ppo"

    def config_class(self) -> type:
        """Its model config dataclass (imports its module)."""
        return _resolve(self.config, f"learner {self.name!r}: config")

    def build(self, dims: Any, config: Any, acting_only: bool = False) -> dict:
        """Its networks, freshly initialised (seed torch first for reproducible weights)."""
        return _resolve(self.builder, f"learner {self.name!r}: builder")(dims, config, acting_only)


_LEARNERS: dict[str, LearnerEntry] = {}
"""name -> entry, in registration order."""


def register_learner(entry: LearnerEntry) -> LearnerEntry:
    """Add ``entry``; a name or colour that is taken is refused."""
    if not isinstance(entry, LearnerEntry):
        raise TypeError(f"entry must be a comat.learners.LearnerEntry, got {type(entry).__name__}")
    if entry.name in _LEARNERS:
        raise ValueError(f"learner {entry.name!r} is registered already")
    taken = {e.colour.lower(): e.name for e in _LEARNERS.values()}
    if entry.colour.lower() in taken:
        raise ValueError(
            f"learner {entry.name!r}: colour {entry.colour} is learner {taken[entry.colour.lower()]!r}'s; "
            "every learner has its own"
        )
    _LEARNERS[entry.name] = entry
    return entry


def learner_names() -> tuple[str, ...]:
    """The registered learners' names, in the order commands and tables list them."""
    return tuple(_LEARNERS)


def learner_entry(name: str) -> LearnerEntry:
    """The entry of learner ``name``; ValueError naming the registered ones otherwise."""
    if name not in _LEARNERS:
        raise ValueError(f"algo must be one of {list(_LEARNERS)}, got {name!r}{_plugin_hint()}")
    return _LEARNERS[name]


def _resolve(target: str, what: str = "") -> Any:
    """The object an import string ``module:attribute`` names; ValueError (one line, after ``what``)
    saying why not."""
    what = f"{what}: " if what else ""
    module, _, attr = target.partition(":")
    try:
        found = importlib.import_module(module)
    except Exception as err:  # whatever the module raises, said in one line
        why = err.msg if isinstance(err, ModuleNotFoundError) and err.name == module else f"{type(err).__name__}: {err}"
        raise ValueError(f"{what}module {module!r} did not import ({' '.join(str(why).split())})") from err
    if not hasattr(found, attr):
        raise ValueError(f"{what}module {module!r} has no {attr!r}")
    return getattr(found, attr)


# The built-in learners, in table order. Each names the config and builder beside its network.
for _entry in (
    LearnerEntry(
        "ippo",
        "IPPO (team advantage)",  # one GAE on the team's reward and mean value, not each robot's own
        "#8c564b",
        "ppo",
        "comat.models.ippo:IppoConfig",
        "comat.models.ippo:build",
        keeps="actors (no critic)",
        outside_envs=True,
    ),
    LearnerEntry(
        "mappo",
        "MAPPO",
        "#2ca02c",
        "ppo",
        "comat.models.mappo:MappoConfig",
        "comat.models.mappo:build",
        uses_state=True,
        team_sized=True,
        keeps="actors (no critic)",
        outside_envs=True,
    ),
    LearnerEntry(
        "qmix",
        "QMIX",
        "#9467bd",
        "qmix",
        "comat.models.qmix:QmixNetConfig",
        "comat.models.qmix:build",
        team_sized=True,
        keeps="agent network (no mixer)",
        outside_envs=True,
    ),
    LearnerEntry(
        "mat",
        "MAT",
        "#1f77b4",
        "ppo",
        "comat.models.mat:MatConfig",
        "comat.models.mat:build",
        team_sized=True,
        autoregressive=True,
        keeps="policy (encoder, decoder, value head)",
        outside_envs=True,
    ),
    LearnerEntry(
        "cash-caps",
        "CASH-caps",
        "#e7ba52",
        "ppo",
        "comat.models.cash_caps:CashCapsConfig",
        "comat.models.cash_caps:build",
        keeps="encoder, hypernetwork (no critic)",
    ),
    LearnerEntry(
        "cash",
        "CASH",
        "#ff7f0e",
        "ppo",
        "comat.models.cash:CashConfig",
        "comat.models.cash:build",
        keeps="encoder, weight and bias hypernetworks, output layer (no critic)",
    ),
    LearnerEntry(
        "comat",
        "COMAT",
        "#d62728",
        "ppo",
        "comat.models.comat:ComatConfig",
        "comat.models.comat:build",
        autoregressive=True,
        exports=True,
        keeps="policy (encoder, decoder, value head)",
    ),
):
    register_learner(_entry)


def load_plugins(spec: str | None = None) -> list[str]:
    """Register the learners named by ``spec`` (default: the :data:`PLUGIN_ENV` variable) and by the
    ``comat.learners`` entry points, each a :class:`LearnerEntry` object. Returns the names
    registered; after registering every entry that loads, one ValueError line names each entry that
    did not, and why."""
    spec = os.environ.get(PLUGIN_ENV, "") if spec is None else spec
    found = [(f"{PLUGIN_ENV} entry {s.strip()!r}", s.strip(), None) for s in spec.split(",") if s.strip()]
    found += [
        (f"entry point {ep.name!r} = {ep.value!r} (group comat.learners)", ep.value, ep)
        for ep in entry_points(group="comat.learners")
    ]
    names, failed = [], []
    for where, target, ep in found:
        try:
            if not _TARGET.match(target):
                raise ValueError("expected module:ENTRY")
            entry = ep.load() if ep is not None else _resolve(target)
            if not isinstance(entry, LearnerEntry):
                raise TypeError(f"{target} is a {type(entry).__name__}, expected a comat.learners.LearnerEntry")
            if _LEARNERS.get(entry.name) == entry:
                continue
            register_learner(entry)
        except (ValueError, TypeError) as err:
            failed.append(f"{where}: {err}")
            continue
        names.append(entry.name)
    if failed:
        raise ValueError("; ".join(failed))
    return names


def plugin_error() -> str | None:
    """Why a learner named by :data:`PLUGIN_ENV` or an entry point did not register when this module
    was imported (one line; None: every one did). Commands print it and stop (exit 2)."""
    return _PLUGIN_ERROR


def _plugin_hint() -> str:
    return f" ({_PLUGIN_ERROR})" if _PLUGIN_ERROR else ""


def not_registered(name: str) -> str:
    """What to say of a learner ``name`` that is not registered here (a run or policy file of a
    learner of one's own, read without it): how to register it."""
    return (
        f"learner {name!r} is not registered here (registered: {', '.join(_LEARNERS)}): register its entry "
        f"with {PLUGIN_ENV}=module:ENTRY (the module on PYTHONPATH) or a comat.learners entry point, as when "
        f"it was trained (docs/write-a-learner.md){_plugin_hint()}"
    )


_PLUGIN_ERROR: str | None = None
try:  # a bad plug-in entry must not stop `import comat.learners`: it is said where a learner is asked for
    load_plugins()
except ValueError as _err:
    _PLUGIN_ERROR = str(_err)
