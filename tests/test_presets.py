"""Presets that set a task's own values (``by_task``), and how overrides meet them."""

import pytest


def test_a_preset_may_set_a_task_of_its_own_and_an_override_beats_it(tmp_path):
    """quick gives HMT twice PCP's budget (by_task); ``total_env_steps=`` on the command line wins."""
    from comat.rl import apply_overrides, load_preset, resolve

    quick = load_preset("quick")
    assert resolve(quick, "comat", "hmt").total_env_steps == 2 * resolve(quick, "comat", "pcp").total_env_steps
    forced = apply_overrides(quick, ["total_env_steps=640"])
    assert {resolve(forced, "mat", t).total_env_steps for t in ("hmt", "pcp")} == {640}
    bad = tmp_path / "bad.yaml"
    for text, message in (
        ("by_task: {xyz: {total_env_steps: 5}}\n", "by_task in preset"),
        ("by_task: {hmt: {seeds: [1]}}\n", "by_task.hmt in preset"),
    ):
        bad.write_text(text)
        with pytest.raises(ValueError, match=message):
            load_preset(bad)


def test_coalitions_trains_one_fixed_team_stored_in_the_config(tmp_path):
    """``coalitions=FILE`` (issue 50's BenchMARL comparison): the run's config holds the team itself,
    its environments play only that team, and a config stored before the key loads as U_train."""
    import yaml

    from comat.envs.base import resolve_coalitions
    from comat.rl import RunConfig, apply_overrides, load_preset, make_run_env, resolve

    team = resolve_coalitions("train", "pcp")[3]
    path = tmp_path / "team.yaml"
    path.write_text(yaml.safe_dump(team.to_dict()))
    quick = load_preset("quick")
    config = resolve(apply_overrides(quick, [f"coalitions={path}"]), "mappo", "pcp")
    assert config.coalitions == [team.to_dict()]
    assert RunConfig.from_dict(yaml.safe_load(yaml.safe_dump(config.to_dict()))) == config  # as config.yaml stores it
    env = make_run_env(config, 4, seed=0)
    try:
        env.reset(seed=0)
        assert len(env.teams()) == 4 and all(t == team for t in env.teams())
    finally:
        env.close()
    assert resolve(quick, "mappo", "pcp").coalitions == "train"
    old = resolve(quick, "mappo", "pcp").to_dict()
    del old["coalitions"]
    assert RunConfig.from_dict(old).coalitions == "train"
    with pytest.raises(ValueError, match="coalitions: .*no such file"):
        resolve(apply_overrides(quick, [f"coalitions={tmp_path / 'missing.yaml'}"]), "mappo", "pcp")
    hmt_team = tmp_path / "hmt.yaml"
    hmt_team.write_text(yaml.safe_dump(resolve_coalitions("train", "hmt")[0].to_dict()))
    with pytest.raises(ValueError, match="coalitions: .*'hmt' team"):
        resolve(apply_overrides(quick, [f"coalitions={hmt_team}"]), "mappo", "pcp")
