"""Training and evaluation at a reality level (issue 29 part 3): the run config's ``reality`` key
(presets, dotted overrides, stored configs, older checkpoints), ``comat train ... reality=nominal``
(recorded, trained under the layer, resumed exactly) and ``comat eval --reality`` (level-named
files, rows that say their level, ``off`` unchanged)."""

import csv
import dataclasses

import pytest
import torch
import yaml
from test_rl import TINY_MODELS, assert_same, tiny

from comat.cli import main
from comat.envs.base import resolve_coalitions
from comat.measure.metrics import read_results
from comat.reality import RealityConfig
from comat.rl import RunConfig, apply_overrides, load_preset, resolve
from comat.rl.checkpoint import load_checkpoint, with_earlier_defaults


def _resolved(overrides, preset=None):
    return resolve(apply_overrides(preset or {"models": TINY_MODELS}, overrides), "comat", "pcp", seed=3)


# -- the run config's reality key ------------------------------------------------------------------
def test_reality_is_a_run_setting_from_presets_and_overrides(tmp_path):
    assert _resolved([]).reality == RealityConfig()  # default: the ideal world
    assert _resolved(["reality=nominal"]).reality == RealityConfig(level="nominal")
    assert _resolved(["reality.level=stress"]).reality == RealityConfig(level="stress")
    # a level and one field changed, in either order (one dotlist would let the later replace the earlier)
    for overrides in (
        ["reality=nominal", "reality.pose_delay_ticks=2"],
        ["reality.pose_delay_ticks=2", "reality=nominal"],
    ):
        assert _resolved(overrides).reality == RealityConfig(level="nominal", pose_delay_ticks=2)
    # one field without a level changes off: that component alone
    assert _resolved(["reality.command_loss_prob=0.5"]).reality.overrides() == {"command_loss_prob": 0.5}
    # a preset's level, its base's fields and the overrides merge field by field
    base = tmp_path / "base.yaml"
    base.write_text(yaml.safe_dump({"models": TINY_MODELS, "reality": {"pose_noise_xy_m": 0.002}}))
    child = tmp_path / "child.yaml"
    child.write_text(yaml.safe_dump({"base": "base.yaml", "reality": "stress"}))
    got = _resolved(["reality.pose_delay_ticks=3"], load_preset(child)).reality
    assert got == RealityConfig(level="stress", pose_noise_xy_m=0.002, pose_delay_ticks=3)


def test_run_config_round_trips_and_older_configs_load_as_off():
    off = tiny("comat")
    stored = off.to_dict()
    assert list(stored)[-3:] == ["reality", "loop", "coalitions"]
    assert stored["reality"] == dataclasses.asdict(RealityConfig())
    assert stored["loop"] == "comat" and stored["coalitions"] == "train"
    assert RunConfig.from_dict(stored) == off
    # a config from before the layer, the loop and the coalitions options (config.yaml or checkpoint
    # without the keys) is an off run with comat's filter on U_train
    older = {k: v for k, v in stored.items() if k not in ("reality", "loop", "coalitions")}
    assert RunConfig.from_dict(older) == off
    earlier = with_earlier_defaults(older)
    assert (earlier["reality"], earlier["loop"], earlier["coalitions"]) == ("off", "comat", "train")
    assert RunConfig.from_dict(with_earlier_defaults(older)) == off
    # a resolved nominal run stores every field and loads back to itself
    custom = tiny("comat", reality={"level": "nominal", "pose_delay_ticks": 2})
    assert custom.to_dict()["reality"]["pose_delay_ticks"] == 2 and custom.to_dict()["reality"]["level"] == "nominal"
    assert RunConfig.from_dict(yaml.safe_load(yaml.safe_dump(custom.to_dict()))) == custom
    assert custom.to_dict() != off.to_dict()  # so resuming it with another layer is refused


@pytest.mark.parametrize(
    "override, message",
    [
        ("reality=medium", "reality.level must be one of ['off', 'nominal', 'stress'], got 'medium'"),
        ("reality.pose_delay_ticks=-1", "reality.pose_delay_ticks must be an integer >= 0 (ticks), got -1"),
        ("reality.pose_hold_prob=1.5", "reality.pose_hold_prob must be a probability in [0, 1], got 1.5"),
        ("reality.pose_delay_ticks=two", "reality.pose_delay_ticks must be int or NoneType, got 'two' (str)"),
        ("reality.delay=1", "unknown key(s) ['delay'] for reality; valid keys: ["),
    ],
)
def test_bad_reality_overrides_get_one_line_errors(tmp_path, capsys, override, message):
    out = tmp_path / "run"
    assert main(["train", "--algo", "comat", "--task", "pcp", "--steps", "6", "--out", str(out), override]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("comat train: error: ") and message in err
    assert not out.exists()


# -- training at a level ---------------------------------------------------------------------------
def _tiny_preset(tmp_path):
    """tests/test_rl.py's tiny preset as a file, for the command line."""
    preset = {
        "eval_every_steps": 10**9,
        "eval_episodes_per_team": 0,
        "checkpoint_every_steps": 6,
        "seeds": [3],
        "ppo": {"num_envs": 2, "rollout_steps": 3, "epochs": 2, "minibatches": 2},
        "models": TINY_MODELS,
    }
    path = tmp_path / "tiny.yaml"
    path.write_text(yaml.safe_dump(preset))
    return str(path)


def test_training_at_nominal_records_the_level_and_resumes_exactly(tmp_path, capsys):
    from comat.rl import make_run_env

    preset = _tiny_preset(tmp_path)
    train = ["train", "--algo", "comat", "--task", "pcp", "--preset", preset, "--quiet"]
    assert main([*train, "--steps", "12", "--out", str(tmp_path / "straight"), "reality=nominal"]) == 0
    assert "reality nominal" in capsys.readouterr().err
    doc = yaml.safe_load((tmp_path / "straight" / "config.yaml").read_text())
    assert doc["config"]["reality"] == dataclasses.asdict(RealityConfig(level="nominal"))
    assert doc["overrides"] == ["reality=nominal"]
    ckpt = load_checkpoint(tmp_path / "straight" / "checkpoint.pt")
    config = RunConfig.from_dict(ckpt["config"])
    assert config.reality == RealityConfig(level="nominal")
    # the run's environments carry the layer, drawn afresh for every episode from its own generator
    env = make_run_env(config, 2, seed=config.seed)
    try:
        same = [resolve_coalitions("train", "pcp")[0]] * 2  # one layout: the keys line up
        env.reset(teams=same)
        layer = env.core.safe.reality
        assert layer is not None and layer.config == config.reality
        first = layer.keys.copy()
        env.reset(teams=same)
        assert not (layer.keys == first).any()
    finally:
        env.close()
    # it trained under the layer: the same run in the ideal world learns other weights
    assert main([*train, "--steps", "12", "--out", str(tmp_path / "off")]) == 0
    off = load_checkpoint(tmp_path / "off" / "checkpoint.pt")
    assert RunConfig.from_dict(off["config"]).reality == RealityConfig()
    assert any(
        not torch.equal(a, b) for a, b in zip(off["trainer"]["policy"].values(), ckpt["trainer"]["policy"].values())
    )
    # interrupted half way and resumed: the same run, bit for bit
    assert main([*train, "--steps", "6", "--out", str(tmp_path / "split"), "reality=nominal"]) == 0
    assert main([*train, "--steps", "12", "--out", str(tmp_path / "split"), "--resume"]) == 0
    resumed = load_checkpoint(tmp_path / "split" / "checkpoint.pt")
    assert resumed["progress"]["env_steps"] == ckpt["progress"]["env_steps"] == 12
    assert_same(ckpt["trainer"], resumed["trainer"], "trainer")
    assert_same(ckpt["env_rngs"], resumed["env_rngs"], "env_rngs")
    assert torch.equal(ckpt["torch_rng"], resumed["torch_rng"])
    # a resume cannot change the level: it is part of the run
    capsys.readouterr()
    assert main([*train, "--out", str(tmp_path / "split"), "--resume", "reality=off"]) == 2
    assert "--resume continues a run with its own settings" in capsys.readouterr().err


# -- evaluation at a level -------------------------------------------------------------------------
def test_eval_at_a_level_writes_its_own_file_and_off_is_unchanged(tmp_path, capsys):
    from comat.rl import train

    train(tiny("comat", reality="nominal"), tmp_path / "run", quiet=True)
    teams = tmp_path / "teams.yaml"
    own = resolve_coalitions("train", "pcp")[:2]
    teams.write_text(yaml.safe_dump({"coalitions": [{"robots": [r.to_dict() for r in t.robots]} for t in own]}))
    run = str(tmp_path / "run")
    ev = ["eval", "--policy", run, "--teams", str(teams), "--no-references"]
    assert main([*ev, "--reality", "nominal"]) == 0
    out = capsys.readouterr()
    assert "reality layer nominal" in out.out and "reality nominal" in out.err
    nominal = read_results(tmp_path / "run" / "evaluation_unicycle_nominal.json")
    assert (tmp_path / "run" / "evaluation_unicycle_nominal.csv").is_file()
    assert not (tmp_path / "run" / "evaluation_unicycle.json").exists()  # the off file is another one
    assert [r["reality"] for r in nominal["rows"]] == ["nominal"] and nominal["reality"] == "nominal"
    assert nominal["reality_config"] == dataclasses.asdict(RealityConfig(level="nominal"))
    assert nominal["trained_reality"] == "nominal"
    # off is the default, whatever the policy trained at; --reality off writes the same bytes
    assert main([*ev, "--out", str(tmp_path / "plain")]) == 0
    assert "reality layer off" in capsys.readouterr().out
    assert main([*ev, "--reality", "off", "--out", str(tmp_path / "flag")]) == 0
    kinds = ("json", "episodes.json.gz", "csv")
    plain = {s: (tmp_path / "plain" / f"evaluation_unicycle.{s}").read_bytes() for s in kinds}
    assert plain == {s: (tmp_path / "flag" / f"evaluation_unicycle.{s}").read_bytes() for s in kinds}
    off = read_results(tmp_path / "plain" / "evaluation_unicycle.json")
    assert off["checkpoint"] == "../run/checkpoint.pt"  # relative to the file's folder
    assert [r["reality"] for r in off["rows"]] == ["off"] and off["reality_config"]["level"] == "off"
    # paired episodes (same teams and starts), played under the layer: the filter works harder
    a, b = off["rows"][0]["per_episode"], nominal["rows"][0]["per_episode"]
    assert [e["team_size"] for e in a] == [e["team_size"] for e in b]
    assert [e["interventions"] for e in a] != [e["interventions"] for e in b]
    # an off evaluation next to the nominal one: neither replaces the other
    assert main([*ev]) == 0
    assert read_results(tmp_path / "run" / "evaluation_unicycle.json") == {**off, "checkpoint": "checkpoint.pt"}
    assert read_results(tmp_path / "run" / "evaluation_unicycle_nominal.json") == nominal
    # the report's robustness table reads the two levels as one component, in the levels' order
    from comat.eval.robustness import robustness_figure, robustness_rows
    from comat.eval.runs import load_run

    every = robustness_rows([load_run(run)])
    rows = [r for r in every if r["metric"] == "progress"]
    assert [(r["component"], r["value"], r["seeds"]) for r in rows] == [("level", "off", 1), ("level", "nominal", 1)]
    assert "fig.png" in robustness_figure(every, tmp_path / "fig")
    capsys.readouterr()
    # a bad level: one line naming the flag, the choices and the value, nothing written
    assert main([*ev, "--reality", "foo", "--out", str(tmp_path / "bad")]) == 2
    err = capsys.readouterr().err
    assert (
        err
        == "comat eval: error: --reality must be one of ['off', 'nominal', 'stress'] or a profile file PROFILE.yaml, "
        "got 'foo'\n"
    )
    assert not (tmp_path / "bad").exists()


def test_evaluate_policies_names_a_custom_layer():
    from comat.eval import evaluate_policies

    own = resolve_coalitions("train", "pcp")[:1]
    result = evaluate_policies(
        None,
        task="pcp",
        sets=[("one", own)],
        references=("constant",),
        progress=lambda s: None,
        reality={"level": "nominal", "pose_delay_ticks": 1},
    )
    assert result["reality"] == "custom" and [r["reality"] for r in result["rows"]] == ["custom"]
    assert result["reality_config"]["pose_delay_ticks"] == 1 and result["trained_reality"] is None
    with pytest.raises(ValueError, match=r"^reality must be one of \['off', 'nominal', 'stress'\].*got 'medium'$"):
        evaluate_policies(None, task="pcp", sets=[("one", own)], reality="medium")


# -- sweeps of one component and the report's robustness curves -----------------------------------------
def test_reality_sweep_writes_its_file_and_the_report_draws_it(tmp_path, capsys):
    from comat.rl import train

    teams = tmp_path / "teams.yaml"
    own = resolve_coalitions("train", "pcp")[:2]
    teams.write_text(yaml.safe_dump({"coalitions": [{"robots": [r.to_dict() for r in t.robots]} for t in own]}))
    runs = []
    for seed in (1, 2):
        run = tmp_path / f"comat_pcp_s{seed}"
        train(dataclasses.replace(tiny("comat"), seed=seed), run, quiet=True)
        ev = ["eval", "--policy", str(run), "--teams", str(teams)]
        assert main([*ev]) == 0
        assert main([*ev, "--reality-sweep", "command_delay_ticks", "--sweep-values", "0", "3", "6"]) == 0
        runs.append(str(run))
    out = capsys.readouterr()
    assert "command_delay_ticks at [0, 3, 6] (others at off)" in out.err
    sweep = read_results(run / "evaluation_unicycle_sweep_command_delay_ticks.json")
    assert sweep["values"] == [0, 3, 6] and sweep["base"] == "off"
    assert [[r["policy"] for r in p["rows"]] for p in sweep["points"]] == [["comat", "heuristic"]] * 3
    heur = [next(r for r in p["rows"] if r["policy"] == "heuristic") for p in sweep["points"]]
    steps = [r["metrics"]["steps"]["mean"] for r in heur]
    assert steps[2] > steps[0]  # six ticks of command delay slow the scripted policy down
    # the value-0 point is the off evaluation's episodes (paired), in fewer fields
    off = read_results(run / "evaluation_unicycle.json")["rows"][0]["per_episode"]
    assert [e["steps"] for e in sweep["points"][0]["rows"][0]["per_episode"]] == [e["steps"] for e in off]
    assert main(["report", *runs, "--out", str(tmp_path / "report")]) == 0
    rows = list(csv.DictReader((tmp_path / "report" / "robustness.csv").read_text().splitlines()))
    prog = [r for r in rows if r["metric"] == "progress"]
    assert [(r["value"], r["seeds"]) for r in prog] == [("0", "2"), ("3", "2"), ("6", "2")]
    assert (tmp_path / "report" / "fig7_robustness.png").is_file()
    # bad sweeps: one line, nothing written
    capsys.readouterr()
    bad = ["eval", "--policy", runs[0], "--teams", str(teams), "--out", str(tmp_path / "bad")]
    assert main([*bad, "--reality-sweep", "delay"]) == 2
    assert "--reality-sweep must be one of the reality layer's numeric fields" in capsys.readouterr().err
    assert main([*bad, "--reality-sweep", "command_loss_prob", "--sweep-values", "0", "0.5", "2"]) == 2
    assert capsys.readouterr().err == (
        "comat eval: error: --sweep-values: RealityConfig.command_loss_prob must be a probability in [0, 1], got 2.0\n"
    )
    assert main([*bad, "--reality-sweep", "command_delay_ticks", "--sweep-values", "0", "1"]) == 2
    assert not (tmp_path / "bad").exists()
