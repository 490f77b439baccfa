"""One grammar across commands: every subcommand's parser walked, the shared flags compared."""

import argparse

import pytest

from comat.cli import build_parser
from comat.cli.args import DEFAULT_SEED, DEFAULT_TEAMS, TASKS, TIERS
from comat.eval import EVAL_SEED
from comat.learners import learner_names
from comat.team import COALITION_SETS

POLICY_COMMANDS = ("rollout", "export", "eval", "probe", "bench viz")

# Flag -> commands that must have it with the same choices (in order) and the same default.
SHARED = {
    "--policy": ("rollout", "eval", "bench viz"),
    "--task": ("rollout", "export", "eval"),
    "--teams": ("rollout", "eval"),
    "--team": ("rollout", "export"),
    "--tier": ("rollout", "eval", "bench viz", "train"),
    "--seed": ("rollout", "export", "eval", "bench viz"),
    "--episodes": ("rollout", "eval"),
    "--force": ("rollout", "eval", "probe", "report"),
    "--tasks": ("bench env",),
}
# Where a flag of that name deliberately differs, and why (each one stated in its --help).
EXCEPTIONS = {
    ("--policy", "export"): "required: an export names what it ships",
    ("--policy", "campaign"): "required: a campaign names what it ships, as export",
    ("--policy", "probe"): "required, a checkpoint only: it probes a learner",
    ("--tier", "demo"): "the demo shows the reference physics (wheels)",
    ("--tier", "export"): "--check's MuJoCo side: unicycle, as replay's twin (no checkpoint to take a tier from)",
    ("--seed", "train"): "the preset's training seed",
    ("--task", "train"): "a registered task or an outside env, outside:MODULE",
    ("--seed", "probe"): "the run's own seed, to replay its training rollout",
    ("--seed", "demo"): "the demo's teams",
    ("--seed", "coalitions"): "the composition sets' seed (the envs use 0)",
    ("--seed", "bench soak"): "the soak's own episodes",
    ("--seed", "replay"): "the twin's reality-layer seed: export --check's first run's, 0",
    ("--tier", "replay"): "the twin's tier: unicycle, the presets', as export --check (a log has no training tier)",
    ("--episodes", "bench viz"): "episodes per timed rollout",
    ("--episodes", "demo"): "teams per row",
    ("--episodes", "bench soak"): "total episodes",
    ("--episodes", "bench safety"): "episodes per scenario (issue 29: >= 50)",
    ("--seed", "bench safety"): "the battery's own episodes",
    ("--seed", "calibrate"): "the simulated calibration run's layer",
    ("--tasks", "bench viz"): "default: a checkpoint's own task",
    ("--episodes", "sweep"): "not given: the recorded sweep's (see the sweep test below)",
    ("--tasks", "sweep"): "not given: the recorded sweep's",
    ("--tier", "sweep"): "not given: the recorded sweep's, else the preset's",
    ("--seed", "validity"): "the held-out validity seed, never used to design a task",
    ("--episodes", "validity"): "5 per coalition, as the committed validity page",
}


def _commands(parser, prefix=""):
    """(command name, parser) of every subcommand, nested ones as 'bench viz'."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                full = f"{prefix} {name}".strip()
                yield full, sub
                yield from _commands(sub, full)


def _options(parser):
    return {opt: a for a in parser._actions for opt in a.option_strings if a.help != argparse.SUPPRESS}


COMMANDS = dict(_commands(build_parser()))


def test_every_policy_command_speaks_the_grammar():
    for name in POLICY_COMMANDS:
        opts = _options(COMMANDS[name])
        assert "--policy" in opts, name
        assert "--checkpoint" not in opts, name  # the old spelling is hidden (still accepted)
    for name, parser in COMMANDS.items():
        opts = _options(parser)
        for flag, action in opts.items():
            if action.dest in ("task", "tasks", "algo") or flag == "--algos":
                if action.dest == "algo" or flag == "--algos":  # bench learn adds comat_paper after comat
                    assert tuple(c for c in action.choices if c in learner_names()) == learner_names(), (name, flag)
                elif action.choices is None:  # train --task: a registered task or outside:MODULE, checked by type
                    assert action.metavar.startswith("{" + ",".join(TASKS) + "}"), (name, flag)
                    assert action.type("pcp") == "pcp" and action.type("outside:m.e") == "outside:m.e", (name, flag)
                    with pytest.raises(argparse.ArgumentTypeError, match="choose from"):
                        action.type("pcpp")
                else:
                    assert tuple(action.choices) == TASKS, (name, flag)  # one order everywhere
            if action.choices is not None and set(action.choices) == set(TIERS):
                assert tuple(action.choices) == TIERS, (name, flag)


@pytest.mark.parametrize("flag", sorted(SHARED))
def test_shared_flags_have_one_spelling_choice_order_and_default(flag):
    specs = {}
    for name, parser in COMMANDS.items():
        action = _options(parser).get(flag)
        if action is None:
            continue
        if (flag, name) in EXCEPTIONS:
            assert "default" in (action.help or "") or action.default is None, (flag, name)
            continue
        default = tuple(action.default) if isinstance(action.default, list) else action.default
        specs[name] = (None if action.choices is None else tuple(action.choices), default, action.nargs)
        if action.default not in (None, False):
            assert "default" in action.help, (flag, name)  # the default is stated in --help
    missing = [c for c in SHARED[flag] if c not in specs]
    assert not missing, (flag, missing)
    assert len(set(specs.values())) == 1, (flag, specs)


def test_the_shared_defaults_are_the_documented_ones():
    assert DEFAULT_SEED == EVAL_SEED and DEFAULT_TEAMS == "both"
    opts = _options(COMMANDS["eval"])
    assert opts["--policy"].default == "heuristic" and opts["--tier"].default is None
    assert opts["--seed"].default == DEFAULT_SEED and opts["--teams"].default == DEFAULT_TEAMS
    for name in ("rollout", "eval"):
        assert all(s in _options(COMMANDS[name])["--teams"].metavar for s in COALITION_SETS)


def test_old_spellings_work_with_a_one_line_note(capsys):
    args = build_parser().parse_args(["eval", "--checkpoint", "r/checkpoint.pt", "--set", "test"])
    assert args.policy == "r/checkpoint.pt" and args.teams == "test"
    err = capsys.readouterr().err.splitlines()
    assert err == [
        "comat: --checkpoint is deprecated and will be removed; use --policy r/checkpoint.pt",
        "comat: --set is deprecated and will be removed; use --teams test",
    ]
    args = build_parser().parse_args(["rollout", "--set", "scale", "--task", "pcp"])
    assert args.teams == "scale"


def test_sweep_flags_not_given_come_from_the_recorded_sweep():
    """``comat sweep``: a grid flag left out means the recorded sweep's value (continuing it), else
    the default its --help states; so they default to None, and their choices follow the grammar."""
    opts = _options(COMMANDS["sweep"])
    for flag in ("--algos", "--tasks", "--seeds", "--preset", "--tier", "--eval-tiers", "--eval-sets", "--episodes"):
        assert opts[flag].default is None and "default" in opts[flag].help, flag
    assert tuple(opts["--tasks"].choices) == TASKS and tuple(opts["--tier"].choices) == TIERS
    assert tuple(opts["--eval-sets"].choices) == COALITION_SETS
