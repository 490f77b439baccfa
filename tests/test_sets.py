"""The composition sets that separate size from capability (issue 28): U_val, U_size, U_cap."""

import numpy as np
import pytest

from comat.cli.args import parse_team, parse_teams
from comat.envs.base import resolve_coalitions
from comat.tasks import env_id
from comat.team import (
    CAPABILITY_RANGES,
    COALITION_SETS,
    SET_LABELS,
    SIZES,
    TASK_TYPES,
    generate_coalitions,
    random_team,
)

TASKS = ("pcp", "hmt")


def _training_band(task, robot_type, k):
    (band,) = CAPABILITY_RANGES[(task, "train")][robot_type][k]
    return band


def _robots(teams):
    return tuple(sorted((r.type, r.capabilities) for r in teams.robots))


def test_every_set_has_a_label_and_a_stream_of_its_own():
    assert COALITION_SETS == ("train", "val", "test", "scale", "size", "capability")
    assert set(SET_LABELS) == set(COALITION_SETS) and SET_LABELS["capability"] == "U_cap"
    for task in TASKS:
        drawn = {split: {_robots(t) for t in generate_coalitions(task, split)} for split in COALITION_SETS}
        for a in COALITION_SETS:
            for b in COALITION_SETS:
                if a < b:  # no two sets share a team: separate random streams
                    assert not drawn[a] & drawn[b], (task, a, b)


@pytest.mark.parametrize("task", TASKS)
def test_capability_robots_lie_outside_the_training_range_in_every_capability(task):
    teams = generate_coalitions(task, "capability")
    assert len(teams) == 20 and {t.size for t in teams} <= {3, 5, 7}
    tt = TASK_TYPES[task]
    sides = set()
    for team in teams:
        for r in team.robots:
            for k, value in enumerate(r.capabilities):
                lo, hi = _training_band(task, r.type, k)
                if lo == hi == 0.0:  # a capability the type does not have (PCP): stays 0
                    assert value == 0.0
                    continue
                assert value < lo or value > hi, (r, k)
                low, high = tt.limits[k]
                assert low < value <= high
                sides.add((r.type, k, value > hi))
    # Both sides of the training range, for every capability every type has.
    used = {(t, k) for t in tt.types for k in range(len(tt.capabilities)) if _training_band(task, t, k)[1] > 0}
    assert sides == {(t, k, above) for t, k in used for above in (False, True)}


def test_a_side_is_drawn_in_proportion_to_its_width():
    # PCP sensing radii of U_cap: [0.18, 0.30) is 0.12 m wide, (0.55, 0.75] 0.20 m: 3/8 below.
    rng = np.random.default_rng(0)
    values = np.array(
        [
            r.capabilities[0]
            for _ in range(400)
            for r in random_team(rng, "pcp", "capability", 10).robots
            if r.type == "sensing"
        ]
    )
    assert values.size > 1500
    assert abs(np.mean(values < 0.30) - 0.375) < 0.03
    below, above = values[values < 0.30], values[values > 0.55]
    assert below.min() >= 0.18 and above.max() <= 0.75
    # Uniform inside each band: the means sit mid-band.
    assert abs(below.mean() - 0.24) < 0.01 and abs(above.mean() - 0.65) < 0.01


@pytest.mark.parametrize("task", TASKS)
def test_val_is_drawn_like_train_and_shares_no_team_with_it(task):
    val, train = generate_coalitions(task, "val"), generate_coalitions(task, "train")
    assert CAPABILITY_RANGES[(task, "val")] == CAPABILITY_RANGES[(task, "train")]
    assert {t.size for t in val} <= set(SIZES["train"]) and len(val) == 20
    assert not {_robots(t) for t in val} & {_robots(t) for t in train}
    assert len({_robots(t) for t in val}) == 20  # nor a team twice


@pytest.mark.parametrize("task", TASKS)
def test_size_covers_2_to_20_with_the_training_ranges(task):
    teams = generate_coalitions(task, "size")
    assert [t.size for t in teams] == [n for n in range(2, 21, 2) for _ in range(2)]
    for team in teams:
        for r in team.robots:
            for k, value in enumerate(r.capabilities):
                lo, hi = _training_band(task, r.type, k)
                assert lo <= value <= hi
    # With another count the sizes still cycle evenly: one of each for 10.
    assert [t.size for t in generate_coalitions(task, "size", count=10)] == list(range(2, 21, 2))


@pytest.mark.parametrize("bad", [0, -3, 2.5, True])
def test_bad_counts_are_refused(bad):
    with pytest.raises(ValueError, match=rf"count must be a positive integer, got {bad!r}"):
        generate_coalitions("pcp", "val", count=bad)


@pytest.mark.parametrize("task", TASKS)
def test_the_new_sets_are_accepted_wherever_a_set_name_is(task):
    for split in ("val", "size", "capability"):
        assert resolve_coalitions(split, task) == generate_coalitions(task, split)
        assert parse_teams(split, task) == [(split, generate_coalitions(task, split))]
    assert parse_team("size:19", task) == generate_coalitions(task, "size")[19]
    assert [name for name, _ in parse_teams("all", task)] == list(COALITION_SETS)
    assert [name for name, _ in parse_teams("both", task)] == ["train", "test"]


@pytest.mark.parametrize("task", ["hmt", "pcp"])
def test_every_set_gives_a_state_by_default(task):
    """U_scale and U_size teams have up to 20 robots: the default state covers them (issue 32)."""
    from comat.envs import make_env

    sizes = {}
    for split in ("train", "scale"):
        env = make_env(env_id(task), coalitions=split, tier="unicycle")
        env.reset(seed=1)
        state = env.state()
        assert state.shape == env.state_space.shape
        sizes[split] = state.shape[0]
    obs = 15 if task == "hmt" else 13
    assert sizes["scale"] - sizes["train"] >= 12 * obs  # 20 robot slots instead of 8
