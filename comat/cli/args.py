"""The one grammar of every ``comat`` command that runs a policy (rollout, export, eval, probe, bench viz).

Shared flags, defined here once so their spelling, choices (in one order) and defaults agree:

===================  =========================================================================
``--policy P``       a policy file (``policy.pt``), a checkpoint file, a run folder (its
                     ``checkpoint.pt``, else its ``policy.pt``), or a reference policy:
                     a rung of the reference ladder: ``heuristic`` (or ``scripted``: reads the
                     task state), ``type_only`` (the same planner knowing types, not capabilities),
                     ``blind`` (neither), ``constant`` (every robot always the task's best single
                     action), ``random``; ``probe`` needs a checkpoint
``--task T``         a registered task (``comat tasks``); inferred from a checkpoint or policy
                     file (a different ``--task`` is an error); needed with a reference policy
``--team TEAM``      one team: ``SET:K`` (coalition K of a set below, e.g. ``capability:3``)
                     or a JSON/YAML file ``{"robots": [...]}``
``--teams SET``      a set of teams: ``train``, ``val``, ``test``, ``scale``, ``size``, ``capability``,
                     ``both`` (train and test), ``all`` (every set), or a file (a coalition list
                     ``{"coalitions": [...]}`` or one team);
                     default ``both``
``--tier T``         ``wheels`` or ``unicycle``; default the checkpoint's training tier, else
                     :data:`comat.config.REFERENCE_TIER`
``--seed S``         default :data:`DEFAULT_SEED` (the evaluation seed; never a training seed)
``--reality L``      ``off``, ``nominal`` or ``stress``: the reality layer the episodes play at
                     (:mod:`comat.reality`); default ``off``, never the policy's training level
``--out`` / ``--force``  created if missing; refused if it would overwrite unless ``--force``;
                     removed again if the command fails (:func:`comat.files.new_outputs`)
===================  =========================================================================

Old spellings keep working for one release with a one-line note on stderr: ``--checkpoint
FILE`` (now ``--policy FILE``) and ``--set SET`` (now ``--teams SET``).
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass
from pathlib import Path

from comat.config import REFERENCE_TIER
from comat.learners import learner_names
from comat.reality.config import REALITY_LEVELS
from comat.tasks import LADDER, RUNG_ALIASES, task_names
from comat.team import COALITION_SETS

__all__ = [
    "DEFAULT_SEED",
    "DEFAULT_TEAMS",
    "REFERENCE_POLICIES",
    "TASKS",
    "TIERS",
    "CommandParser",
    "PolicyArg",
    "VersionAction",
    "add_force",
    "add_policy",
    "add_reality",
    "add_reality_sweep",
    "add_seed",
    "add_task",
    "add_team",
    "add_teams",
    "add_tier",
    "comat_version",
    "int_at_least",
    "parse_team",
    "parse_teams",
    "reality_arg",
    "resolve_policy_arg",
]

TASKS = task_names()
"""Task choices, in this order in every command (the registered tasks, :mod:`comat.tasks`)."""
TIERS = ("wheels", "unicycle")
REFERENCE_POLICIES = (*LADDER, *RUNG_ALIASES)
"""The reference ladder's rungs (:mod:`comat.envs.heuristics`) and their other names."""
DEFAULT_SEED = 2_000_003
"""Default ``--seed`` of episodes a command plays (comat.eval.evaluate.EVAL_SEED)."""
DEFAULT_TEAMS = "both"
TEAM_SETS = (*COALITION_SETS, "both", "all")


def int_at_least(minimum: int):
    """An argparse ``type``: a whole number ``>= minimum``, else a usage error naming the value."""
    wanted = "a positive integer" if minimum == 1 else f"a whole number {minimum} or more"

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = None
        if value is None or value < minimum:
            raise argparse.ArgumentTypeError(f"expected {wanted}, got {text!r}")
        return value

    return parse


class CommandParser(argparse.ArgumentParser):
    """An ``ArgumentParser`` whose usage errors take one line, what was wrong and where the help is,
    not argparse's 7-9-line usage block before it (a typo in ``--algo`` should not bury its own error).
    Subcommands' parsers are of the same class (argparse's ``parser_class`` default)."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message} (usage: {self.prog} --help)\n")


class _Deprecated(argparse.Action):
    """An old spelling: stores like the new one, says so on stderr (one line)."""

    def __init__(self, option_strings, dest, new: str, **kwargs) -> None:
        self.new = new
        super().__init__(option_strings, dest, **kwargs)

    def __call__(self, parser, namespace, values, option_string=None) -> None:
        print(f"comat: {option_string} is deprecated and will be removed; use {self.new} {values}", file=sys.stderr)
        setattr(namespace, self.dest, values)


def comat_version() -> str:
    """The package version and the source commit it runs from (when known)."""
    from comat._version import __version__
    from comat.rl import source_commit

    commit = source_commit()
    return __version__ + (f" ({commit})" if commit and commit != "unknown" else "")


class VersionAction(argparse.Action):
    """``comat --version``, computed only when asked (it asks git for the commit)."""

    def __init__(self, option_strings, dest, **kwargs):
        super().__init__(option_strings, dest, nargs=0, default=argparse.SUPPRESS, **kwargs)

    def __call__(self, parser, namespace, values, option_string=None):
        print(f"comat {comat_version()}")
        parser.exit()


def add_policy(
    p: argparse.ArgumentParser,
    *,
    required: bool = False,
    references: tuple[str, ...] = REFERENCE_POLICIES,
    checkpoint_alias: bool = True,
    policy_files: bool = True,
) -> None:
    """``--policy`` (default heuristic unless ``required``) and the deprecated ``--checkpoint``;
    ``policy_files=False``: a command that needs the checkpoint (probe).

    A required ``--policy`` is checked by :func:`resolve_policy_arg`, not argparse, so that the old
    spelling still satisfies it."""
    refs = "|".join(references)
    p.add_argument(
        "--policy",
        default=None if required else "heuristic",
        metavar=f"{'POLICY|' if policy_files else ''}CHECKPOINT|RUN_FOLDER{'|' + refs if refs else ''}",
        help=(
            "a policy.pt, a checkpoint.pt, a run folder (its checkpoint.pt, else its policy.pt)"
            if policy_files
            else "a checkpoint.pt or a run folder (its checkpoint.pt; a policy.pt has no value estimates)"
        )
        + (f", or a reference policy ({', '.join(references)})" if references else "")
        + (" (required)" if required else " (default: %(default)s)"),
    )
    if checkpoint_alias:
        p.add_argument("--checkpoint", dest="policy", action=_Deprecated, new="--policy", help=argparse.SUPPRESS)


def add_task(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--task", choices=TASKS, default=None, help="task (default: the checkpoint's; needed with a reference policy)"
    )


def add_team(p: argparse.ArgumentParser, *, required: bool = False, note: str = "") -> None:
    """``--team``; ``note`` ends its help (rollout's: that it replaces --teams, which export has not)."""
    p.add_argument(
        "--team",
        required=required,
        default=None,
        metavar="SET:K|FILE",
        help=f"one team: {', '.join(f'{s}:K' for s in COALITION_SETS)} (coalition K of that set) or a "
        'JSON/YAML file {"robots": [...]}' + note,
    )


def add_teams(p: argparse.ArgumentParser, *, set_alias: bool = True) -> None:
    p.add_argument(
        "--teams",
        default=DEFAULT_TEAMS,
        metavar="|".join(TEAM_SETS) + "|FILE",
        help="a set of teams: " + ", ".join(COALITION_SETS) + " (the composition sets), both = train and "
        "test, all = " + " and ".join(COALITION_SETS) + ", or a coalition file "
        '({"coalitions": [...]} or one team) (default: %(default)s)',
    )
    if set_alias:
        p.add_argument("--set", dest="teams", action=_Deprecated, new="--teams", help=argparse.SUPPRESS)


def add_tier(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--tier",
        choices=TIERS,
        default=None,
        help=f"dynamics tier (default: the checkpoint's training tier; {REFERENCE_TIER} for a reference policy)",
    )


def add_seed(p: argparse.ArgumentParser, what: str = "seed of the episodes") -> None:
    p.add_argument("--seed", type=int, default=DEFAULT_SEED, help=f"{what} (default: %(default)s)")


def add_reality(p: argparse.ArgumentParser, meaning: str | None = None) -> None:
    """``--reality`` (default off); ``meaning``: its help where it is not the layer the episodes play at."""
    p.add_argument(
        "--reality",
        default="off",
        metavar="{" + ",".join(REALITY_LEVELS) + ",PROFILE.yaml}",
        help=meaning
        or "reality layer the episodes play at (late, noisy poses, lost commands, lagging motors: "
        "docs/reality.md); default: off, the ideal world, NOT the level the policy trained at",
    )


def add_reality_sweep(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--reality-sweep",
        default=None,
        metavar="COMPONENT",
        help="play at several values of one reality field (e.g. pose_delay_ticks, command_loss_prob, "
        "motor_tau_max_s), the others at --reality's level; the heuristic plays next to a trained policy "
        "unless --no-references",
    )
    p.add_argument(
        "--sweep-values",
        type=float,
        nargs="+",
        default=None,
        metavar="V",
        help="the values (three or more; default: off, nominal, stress and beyond, comat.eval.robustness.SWEEP_VALUES)",
    )


def reality_arg(value: str, name: str = "--reality") -> str:
    """``--reality`` (or the option ``name``) checked in the command (a one-line error, not
    argparse's usage block): a level, or a profile file ``*.yaml`` from ``comat calibrate``."""
    if value.endswith((".yaml", ".yml")):
        from comat.reality.config import resolve_reality

        resolve_reality(value, name)  # the file's errors now, before anything runs
        return value
    if value not in REALITY_LEVELS:
        raise ValueError(f"{name} must be one of {list(REALITY_LEVELS)} or a profile file PROFILE.yaml, got {value!r}")
    return value


def add_filter(p: argparse.ArgumentParser) -> None:
    """``--filter`` and ``--filter-reality``: the loop an exported ``main.py`` filters its commands with
    (``comat export``, ``comat campaign``)."""
    p.add_argument(
        "--filter",
        default="comat",
        metavar="{comat,robotarium}",
        help="what main.py filters its commands with: comat's filter (shipped in deployed_loop.py; robust "
        "to late and noisy poses, robots that stop are obstacles: clean in the safety battery at nominal "
        "with faults, docs/safety.md) or the installed rps's own barrier (default: %(default)s)",
    )
    p.add_argument(
        "--filter-reality",
        default="nominal",
        metavar="LEVEL|PROFILE",
        help="the reality level or calibrated profile comat's filter is made robust to (default: %(default)s)",
    )


def add_force(p: argparse.ArgumentParser) -> None:
    p.add_argument("--force", action="store_true", help="replace output files that already exist (default: refuse)")


@dataclass(frozen=True)
class PolicyArg:
    """A resolved ``--policy``: a reference policy's name, or a trained policy's file with its run's
    facts. ``checkpoint`` is that file, a ``checkpoint.pt`` or a ``policy.pt`` (``kind`` says which;
    both load with :func:`comat.rl.policy.load_policy`)."""

    name: str
    task: str
    checkpoint: Path | None = None
    algo: str | None = None
    trained_tier: str | None = None
    kind: str | None = None
    """"checkpoint" or "policy" (a policy file); None for a reference policy."""
    shipped: str | None = None
    """``pretrained:NAME`` for a policy that ships with comat, else None."""

    @property
    def label(self) -> str:
        """How a command's header names the policy: ``pretrained:NAME (comat)``, a file with what it
        is (``runs/x/policy.pt (comat policy file)``), or a reference policy's name."""
        if self.checkpoint is None:
            return self.name
        noun = "policy file" if self.kind == "policy" else "checkpoint"
        return f"{self.shipped or self.checkpoint} ({self.algo}{'' if self.shipped else ' ' + noun})"

    @property
    def default_out(self) -> Path | None:
        """Where a command writes when ``--out`` is not given: a trained policy's run folder, but for a
        shipped policy ``runs/pretrained-NAME`` (nothing is ever written into the installed package,
        and each shipped policy gets its own folder), and for a reference policy ``runs/POLICY-TASK``
        (``runs/type_only-forage``)."""
        if self.shipped is not None:
            return Path("runs") / self.shipped.replace(":", "-")
        if self.checkpoint is None:
            return Path("runs") / f"{self.name}-{self.task}"
        return self.checkpoint.parent

    @property
    def tier(self) -> str:
        """The default tier: the training tier of a checkpoint, else :data:`comat.config.REFERENCE_TIER`."""
        return self.trained_tier or REFERENCE_TIER


def resolve_policy_arg(
    policy: str | None,
    task: str | None,
    references: tuple[str, ...] = REFERENCE_POLICIES,
    algos: tuple[str, ...] | None = None,
    need_checkpoint: str | None = None,
    why: str = "",
) -> PolicyArg:
    """Check ``--policy`` against ``--task`` (ValueError naming the flag, expected and got).

    ``algos``: the learners whose policies the command takes (default: every registered one);
    ``why``: the reason it takes only those, said when another's is given.

    ``need_checkpoint``: why the command needs the whole learner (e.g. "comat probe reads the
    learner's value estimates"); a policy file is then refused with that reason."""
    from comat.envs.outside import is_outside
    from comat.rl import POLICY_FORMAT, PREFIX, PRETRAINED, load_checkpoint, load_trained, policy_file_of, shipped_name

    shipped = ", ".join(PREFIX + name for name in PRETRAINED)
    what = (
        "a checkpoint.pt or a run folder"
        if need_checkpoint
        else f"a policy.pt, a checkpoint.pt, a run folder, a shipped policy ({shipped})"
    )
    if policy is None:
        raise ValueError(
            f"--policy is required: {what}" + (f", or one of {', '.join(references)}" if references else "")
        )
    if policy in REFERENCE_POLICIES:
        if policy not in references:
            kinds = "a checkpoint or run folder" if need_checkpoint else "a policy file, checkpoint or run folder"
            raise ValueError(
                f"--policy must be {kinds}"
                + (f" or one of {list(references)}" if references else "")
                + f" here, got {policy!r}"
            )
        if task is None:
            raise ValueError(f"--task is needed with --policy {policy} (a reference policy has no task of its own)")
        return PolicyArg(RUNG_ALIASES.get(policy, policy), task)
    path = Path(policy)
    if not path.exists() and not policy.startswith("pretrained:"):  # comat.rl.policy.PRETRAINED: policy_file_of
        refs = f", or one of {', '.join(references)}" if references else ""
        raise ValueError(f"--policy must be {what}{refs}, got {policy!r} (no such file)")
    path = policy_file_of(path, need_checkpoint)
    try:  # CheckpointError (a ValueError) names a foreign or corrupt file
        data = load_checkpoint(path) if need_checkpoint else load_trained(path)
    except ValueError as err:
        if need_checkpoint and "is a comat policy file" in str(err):
            raise ValueError(
                f"--policy {policy!r} is a policy file (the weights to act only): {need_checkpoint}; "
                "give the run's checkpoint.pt"
            ) from err
        raise
    kind = "policy" if data["format"] == POLICY_FORMAT else "checkpoint"
    noun = "policy file" if kind == "policy" else "checkpoint"
    if is_outside(data["task"]):  # trained on an env comat did not write
        raise ValueError(
            f"--policy {policy!r} is a {noun} for outside task {data['task']!r}; this command runs comat's tasks "
            "only (an outside run's evaluation is its eval.csv and summary.json: docs/commands.md#train-outside)"
        )
    if task is not None and task != data["task"]:
        raise ValueError(f"--task {task!r} disagrees with the {noun}, which is for task {data['task']!r} ({path})")
    algos = learner_names() if algos is None else algos
    if data["algo"] not in algos:
        raise ValueError(
            f"--policy must be a checkpoint or policy file of {'/'.join(algos)} here{': ' + why if why else ''}, "
            f"got a {data['algo']} {noun} ({path})"
        )
    tier = (data.get("config") or {}).get("tier")
    return PolicyArg(f"{data['algo']} {kind}", data["task"], path, data["algo"], tier, kind, shipped_name(path))


def _read_team_file(value: str, task: str, flag: str):
    """A team (dict with 'robots') or a coalition list (dict with 'coalitions') from a JSON/YAML file."""
    import yaml

    path = Path(value)
    expected = "a JSON/YAML file with {'robots': [...]}" + (" or {'coalitions': [...]}" if flag == "--teams" else "")
    if not path.is_file():
        why = "a folder" if path.is_dir() else "no such file"
        return None, f"{flag} must be {_team_forms(flag)}, got {value!r} ({why})"
    try:
        data = yaml.safe_load(path.read_bytes().decode("utf-8"))
    except (UnicodeDecodeError, yaml.YAMLError) as err:
        return None, f"{flag} {value!r} must be {expected}, got a file that is not JSON/YAML ({type(err).__name__})"
    if data is None:
        return None, f"{flag} {value!r} must be {expected}, got a file that is empty"
    if not isinstance(data, dict):
        return None, (
            f"{flag} {value!r} must hold a JSON object (YAML mapping) {{'robots': [...]}}, got a {type(data).__name__}"
        )
    if not {"robots", "coalitions"} & set(data):
        return None, f"{flag} {value!r} must be {expected}, got a mapping with keys {sorted(data)}"
    return data, None


def _team_forms(flag: str) -> str:
    sets = ", ".join(f"'{s}:K'" for s in COALITION_SETS)
    if flag == "--team":
        return f"{sets} or a JSON/YAML file with {{'robots': [...]}}"
    return f"one of {list(TEAM_SETS)} or a file with {{'coalitions': [...]}} or {{'robots': [...]}}"


def parse_team(value: str, task: str, flag: str = "--team"):
    """A TeamSpec from ``SET:K`` (coalition K of a set of :data:`comat.team.COALITION_SETS`, e.g.
    ``capability:3``) or a team file."""
    from comat.envs.base import resolve_coalitions
    from comat.team import TeamSpec

    split, sep, index = value.partition(":")
    if sep and split in COALITION_SETS:
        teams = resolve_coalitions(split, task)
        if not index.isdigit() or int(index) >= len(teams):
            raise ValueError(f"{flag} {value!r}: index must be 0..{len(teams) - 1}, got {index!r}")
        return teams[int(index)]
    data, error = _read_team_file(value, task, flag)
    if error:
        raise ValueError(error)
    if "robots" not in data:
        raise ValueError(f"{flag} {value!r} must hold one team {{'robots': [...]}}, got a coalition list (use --teams)")
    return TeamSpec.from_dict({"task": task, **data})


def parse_teams(value: str, task: str) -> list[tuple[str, list]]:
    """``--teams``: ``[(set name, teams), ...]`` — the named sets, or one set read from a file
    (named by its path)."""
    from comat.envs.base import resolve_coalitions
    from comat.team import TeamSpec

    if value in TEAM_SETS:
        names = {"both": ["train", "test"], "all": list(COALITION_SETS)}.get(value, [value])
        return [(name, resolve_coalitions(name, task)) for name in names]
    data, error = _read_team_file(value, task, "--teams")
    if error:
        raise ValueError(error)
    raw = data.get("coalitions", [data])
    if not isinstance(raw, list) or not raw:
        raise ValueError(f"--teams {value!r}: 'coalitions' must be a non-empty list of teams, got {raw!r:.80}")
    teams = []
    for i, t in enumerate(raw):
        if not isinstance(t, dict):
            raise ValueError(f"--teams {value!r}: coalition {i} must be a mapping with 'robots', got {t!r:.80}")  # noqa: TRY004 - bad file content
        team = TeamSpec.from_dict({"task": task, **t})
        if team.task != task:
            raise ValueError(f"--teams {value!r}: coalition {i} is a {team.task!r} team, but the policy runs {task!r}")
        teams.append(team)
    return [(value, teams)]
