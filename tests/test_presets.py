"""Presets that set a task's own values (``by_task``), and how overrides meet them."""

import pytest


def test_a_preset_may_set_a_task_of_its_own_and_an_override_beats_it(tmp_path):
    """quick gives HMT twice PCP's budget (by_task); ``total_env_steps=`` on the command line wins."""
    from comat.rl.config import apply_overrides, load_preset, resolve

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
