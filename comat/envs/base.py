"""PettingZoo ``ParallelEnv`` base for the Robotarium tasks: one environment over :class:`TaskCore`.

``possible_agents`` is the superset ``robot_0 … robot_{M-1}`` (M = the largest team this
environment may get); ``agents`` is this episode's team, which changes at every reset: a
coalition drawn from the environment's set, or the team given to the constructor or to
``reset(options={"team": ...})``. Robot type and capabilities are observation features, never
part of an agent's name.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, ClassVar

import gymnasium
import numpy as np
from gymnasium import spaces
from pettingzoo import ParallelEnv

from comat.envs.core import TaskCore
from comat.envs.options import EnvOptions
from comat.envs.render import EpisodeFrames
from comat.team import COALITION_SETS, TeamSpec, generate_coalitions, load_coalitions, load_team

__all__ = ["COALITION_SEED", "TaskEnv", "build_core", "resolve_coalitions", "resolve_team", "team_source"]

COALITION_SEED = 0
"""Seed of the paper's composition sets (``comat.team.COALITIONS_DIR`` holds the same teams as YAML)."""


def resolve_team(value: Any, task: str, name: str = "team") -> TeamSpec:
    """A TeamSpec from a TeamSpec, a mapping ``{"robots": [...]}`` (task optional), a plain list of
    robots ``[{"type": ..., "capabilities": [...]}, ...]``, or the path of a JSON/YAML file holding
    one team — the forms ``--team`` takes on the command line."""
    if isinstance(value, TeamSpec):
        team = value
    elif isinstance(value, Mapping):
        team = TeamSpec.from_dict({"task": task, **value})
    elif isinstance(value, (str, Path)):
        if not Path(value).is_file():
            raise ValueError(
                f"{name} must be a team file (JSON/YAML {{'robots': [...]}}), got {str(value)!r} (no such file)"
            )
        team = load_team(value, task)
    elif isinstance(value, Sequence) and value and all(isinstance(r, Mapping) for r in value):
        team = TeamSpec.from_dict({"task": task, "robots": list(value)})
    else:
        raise TypeError(
            f"{name} must be a TeamSpec, a mapping with 'robots', a list of robots "
            f"[{{'type': ..., 'capabilities': [...]}}, ...] or a team file path, got {value!r:.80}"
        )
    if team.task != task:
        raise ValueError(f"{name} is a {team.task!r} team, but this environment runs {task!r}")
    return team


_SET_NAMES = ", ".join(repr(s) for s in COALITION_SETS)


def resolve_coalitions(value: Any, task: str) -> list[TeamSpec]:
    """The coalition set: a set name (:data:`comat.team.COALITION_SETS`: train, val, test, scale,
    size, capability), a YAML path, or a list of teams."""
    if isinstance(value, str) and value in COALITION_SETS:
        return generate_coalitions(task, value, seed=COALITION_SEED)
    if isinstance(value, (str, Path)):
        if not Path(value).is_file():
            raise ValueError(
                f"coalitions must be one of {_SET_NAMES}, a YAML path or a non-empty list of teams, got {str(value)!r} "
                "(no such file)"
            )
        teams = load_coalitions(value, task)
    elif isinstance(value, Sequence) and len(value) > 0:
        teams = [resolve_team(t, task, f"coalitions[{i}]") for i, t in enumerate(value)]
    else:
        raise ValueError(
            f"coalitions must be one of {_SET_NAMES}, a YAML path or a non-empty list of teams, got {value!r}"
        )
    for i, t in enumerate(teams):
        if t.task != task:
            raise ValueError(f"coalitions[{i}] is a {t.task!r} team, but this environment runs {task!r}")
    return teams


def team_source(task: Any, coalitions: Any, team: Any, max_robots: Any) -> tuple[list[TeamSpec], TeamSpec | None, int]:
    """Checked coalition set, fixed team (or None) and number of robot slots for ``task``.

    ``task``: the task's name, or the task-logic instance, whose per-env arrays are then sized for
    the largest team it may get here (``fit_teams``: PCP's prey slots come from the largest
    coalition, not from ``max_robots``, so a 20-slot baseline on U_train keeps 6 prey slots).
    """
    name = task if isinstance(task, str) else task.name
    teams = resolve_coalitions(coalitions, name)
    fixed = None if team is None else resolve_team(team, name)
    largest = max([t.size for t in teams] + ([fixed.size] if fixed else []))
    if max_robots is not None and (
        isinstance(max_robots, bool) or not isinstance(max_robots, int) or max_robots < largest
    ):
        raise ValueError(f"max_robots must be an integer >= the largest team ({largest}), got {max_robots!r}")
    if not isinstance(task, str):
        task.check_team_size(largest)  # the largest team the task takes, said as a limit
    if not isinstance(task, str) and hasattr(task, "fit_teams"):
        task.fit_teams(largest)
    return teams, fixed, max_robots or largest


def build_core(
    task: Any, num_envs: int, options: EnvOptions, state_robots: int | None = None
) -> tuple[list[TeamSpec], TeamSpec | None, TaskCore]:
    """The coalition set, the fixed team (or None) and the engine of ``num_envs`` environments of
    ``task`` (a task-logic instance) run with ``options``.

    ``state_robots``: the state's robots where ``options`` leaves them open (None: the robot
    slots, at least 8, as a PettingZoo env has it; a vector env passes 8).
    """
    teams, fixed, slots = team_source(task, options.coalitions, options.team, options.max_robots)
    if options.state_robots is not None:
        state_robots = options.state_robots
    elif state_robots is None:
        state_robots = max(8, slots)
    core = TaskCore(
        task,
        num_envs,
        slots,
        options.sim_config(),
        options.safety,
        options.ticks_per_step,
        state_robots,
        options.reality,
    )
    return teams, fixed, core


class _SatOut(dict):
    """A reset dict keyed by this episode's team; looking up an agent that sits the episode out gives
    ``blank()`` (a plain ``in`` test and iteration see the team only)."""

    def __init__(self, items: dict, out: set[str], blank) -> None:
        super().__init__(items)
        self._out, self._blank = out, blank

    def __missing__(self, agent: str):
        if agent in self._out:
            return self._blank()
        raise KeyError(agent)

    def __reduce__(self):  # copies (TorchRL deep-copies it) keep the lookup
        return type(self), (dict(self), self._out, self._blank)


class TaskEnv(ParallelEnv):
    """A Robotarium task as a PettingZoo parallel environment (subclasses set ``task_cls``).

    Keyword arguments (all optional):
        coalitions, team, tier, sim, safety, ticks_per_step, max_robots, state_robots, reality: the
            options every env API shares (:class:`comat.envs.options.EnvOptions`, each described
            there). ``coalitions`` defaults to "train" (each reset draws one of its teams),
            ``tier`` to "wheels", ``reality`` to "off" (the ideal world; "nominal", "stress", a
            profile, a :class:`comat.reality.RealityConfig` or a mapping of its fields, e.g.
            ``{"level": "nominal", "pose_delay_ticks": 2}``: observations, waypoints, controller
            and filter then read measured poses; rewards and metrics true ones). ``state_robots``
            defaults to 8, or the env's robot slots when its teams are larger (e.g. 20 for
            "scale" and "size"), so every set has a ``state()``.
        render_mode: None (default) or "rgb_array": ``render()`` then returns the arena drawn
            top-down, an (H, W, 3) uint8 frame (:mod:`comat.envs.render`; matplotlib, headless).
        task options: see each task (e.g. PCP ``n_prey``: a fixed prey count instead of the
            rule K(N)). A reset's team (``options={"team": ...}``) must not need more task slots
            than the largest team of the set or fixed team (PCP: prey), else ValueError.
    """

    metadata: ClassVar[dict] = {"name": "", "render_modes": ["rgb_array"], "is_parallelizable": True}
    task_cls: type = object

    def __init__(self, *, render_mode: str | None = None, **options: Any) -> None:
        if render_mode not in (None, *self.metadata["render_modes"]):
            raise ValueError(f"render_mode must be None or one of {self.metadata['render_modes']}, got {render_mode!r}")
        self.render_mode = render_mode
        self.env_options, task_options = EnvOptions.split(options)
        """The env options this environment was made with."""
        self.task = self.task_cls(**task_options)
        self.coalitions, self.fixed_team, self.core = build_core(self.task, 1, self.env_options)
        self.possible_agents = [f"robot_{i}" for i in range(self.core.N)]
        self.agents: list[str] = []
        self._np_random = np.random.default_rng()
        # One space object for every agent (PettingZoo wants the same object on every call).
        self._observation_space = spaces.Box(-np.inf, np.inf, (self.task.obs_size(),), np.float64)
        self._action_space = spaces.Discrete(5)
        self.state_space = spaces.Box(-np.inf, np.inf, (self.core.state_size(),), np.float64)
        self._frames = None
        self.render_caption = self.metadata["name"]
        """First line drawn above every rendered frame (e.g. the policy and the episode)."""
        if render_mode == "rgb_array":
            self._frames = EpisodeFrames()

    # -- spaces ---------------------------------------------------------------------------------
    def observation_space(self, agent: str) -> spaces.Box:
        return self._observation_space

    def action_space(self, agent: str) -> spaces.Discrete:
        return self._action_space

    # -- API --------------------------------------------------------------------------------------
    def reset(self, seed: int | None = None, options: dict | None = None):
        if seed is not None:
            self._np_random = np.random.default_rng(seed)
        options = options or {}
        if options.get("team") is not None:
            team = resolve_team(options["team"], self.task.name, "options['team']")
        elif self.fixed_team is not None:
            team = self.fixed_team
        else:
            team = self.coalitions[int(self._np_random.integers(len(self.coalitions)))]
        if team.size > self.core.N:
            raise ValueError(
                f"team of {team.size} robots is larger than this environment's {self.core.N} agents; "
                "construct it with max_robots >= the team size"
            )
        self.team = team
        if self._frames is not None:
            self._frames.close()  # its tick tap follows the old team's rows
        self.core.reset([0], [team], [self._np_random])
        if self.state_space.shape[0] != self.core.state_size():  # PCP grew its prey slots for this team
            self.state_space = spaces.Box(-np.inf, np.inf, (self.core.state_size(),), np.float64)
        if self._frames is not None:
            self._frames.begin(self.core, 0)
        self.agents = self.possible_agents[: team.size]
        obs = self._obs()
        # The rest of possible_agents sit this episode out, done before it starts. The dicts hold this
        # team's keys (PettingZoo's conversions want exactly these); a wrapper that reads every possible
        # agent at reset (TorchRL sizes its arrays by possible_agents) gets a zero observation, an empty info.
        out = set(self.possible_agents[team.size :])
        blank = np.zeros_like(obs[self.agents[0]])
        return _SatOut(obs, out, lambda: blank.copy()), _SatOut({a: {} for a in self.agents}, out, dict)

    def step(self, actions: dict):
        if not self.agents:
            raise RuntimeError("step() called after the episode ended; call reset()")
        act = np.zeros((1, self.core.N), dtype=np.int64)
        missing = [a for a in self.agents if a not in actions]
        extra = [a for a in actions if a not in self.possible_agents]
        if missing or extra:
            raise ValueError(
                f"actions must cover the agents {self.agents} (those of the other possible_agents "
                f"are ignored); missing {missing}, not possible agents {extra}"
            )
        for i, a in enumerate(self.agents):
            value = actions[a]
            if isinstance(value, np.ndarray) and value.shape == ():
                value = value.item()
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not 0 <= value < 5:
                raise ValueError(f"action of {a} must be an integer in [0, 5) (stay, +x, -x, +y, -y), got {value!r}")
            act[0, i] = int(value)
        res = self.core.step(act)
        if self._frames is not None:
            self._frames.after_step(float(res.rewards[0]))
        agents = list(self.agents)
        obs = self._obs()
        reward = float(res.rewards[0])
        term, trunc = bool(res.terminated[0]), bool(res.truncated[0])
        info = {f"reward/{k}": float(v[0]) for k, v in res.terms.items()}
        if term or trunc:
            info.update({f"episode/{k}": v for k, v in self.core.episode_metrics(0).items()})
            self.agents = []
        return (
            obs,
            {a: reward for a in agents},
            {a: term for a in agents},
            {a: trunc for a in agents},
            {a: dict(info) for a in agents},
        )

    def state(self) -> np.ndarray:
        """Centralized state: task-global features, then ``state_robots`` robots' observations."""
        return self.core.global_state()[0]

    def graph(self) -> dict[str, np.ndarray]:
        """This team's graph (see :meth:`TaskCore.graph`), unpadded: N = team size."""
        n = self.team.size
        g = self.core.graph()
        return {
            "nodes": g["nodes"][0, :n],
            "node_type": g["node_type"][0, :n],
            "edge_attr": g["edge_attr"][0, :n, :n],
            "edge_type": g["edge_type"][0, :n, :n],
            "edge_mask": g["edge_mask"][0, :n, :n],
        }

    def render(self) -> np.ndarray | None:
        """With ``render_mode="rgb_array"``: the arena now, (H, W, 3) uint8 (H, W =
        :data:`comat.envs.render.FRAME_SIZE`); robots by type with their capability radii, trails,
        prey or material, and where the safety filter changed a command in the last step.
        Without a render mode: a warning and None (as Gymnasium and PettingZoo envs do)."""
        if self.render_mode is None:
            gymnasium.logger.warn("render() called without a render_mode; make the env with render_mode='rgb_array'")
            return None
        self._frames.title = self.render_caption
        return self._frames.frame()  # RuntimeError before the first reset

    def close(self) -> None:
        if self._frames is not None:
            self._frames.close()

    def _obs(self) -> dict[str, np.ndarray]:
        obs = self.core.observe()[0]
        return {a: obs[i].copy() for i, a in enumerate(self.possible_agents[: self.team.size])}
