from pathlib import Path

import numpy as np
import pytest

from comat.team import (
    CAPABILITY_RANGES,
    COALITIONS_DIR,
    SIZES,
    TASK_TYPES,
    RobotSpec,
    TeamSpec,
    generate_coalitions,
    load_coalitions,
)

ROOT = Path(__file__).resolve().parents[1]


def test_the_checkout_train_folder_is_the_package_data():
    """train/configs and train/coalitions are the package's own folders (one copy to edit), so
    what a user edits there is what a wheel ships."""
    from comat.rl.config import PRESETS_DIR

    for link, target in (("configs", PRESETS_DIR), ("coalitions", COALITIONS_DIR)):
        if not (ROOT / "train" / link).exists():
            pytest.skip("not a checkout")
        assert (ROOT / "train" / link).resolve() == target
    assert sorted(p.name for p in COALITIONS_DIR.glob("*.yaml")) == sorted(
        f"{task}_{split}.yaml" for task, split in CAPABILITY_RANGES
    )


@pytest.mark.parametrize("task,split", sorted(CAPABILITY_RANGES))
def test_sets_follow_their_definition(task, split):
    teams = generate_coalitions(task, split)
    assert len(teams) == 20
    assert {t.size for t in teams} <= set(SIZES[split])
    types = TASK_TYPES[task].types
    for t in teams:
        # one of each type while the team has room (an optional type comes last: Arctic's scout)
        assert {r.type for r in t.robots} == set(types[: t.size])
        for r in t.robots:
            for value, bands in zip(r.capabilities, CAPABILITY_RANGES[(task, split)][r.type]):
                assert any(lo <= value <= hi for lo, hi in bands), (value, bands)


def test_sets_are_reproducible_and_seed_dependent():
    a = generate_coalitions("pcp", "train", seed=0)
    assert a == generate_coalitions("pcp", "train", seed=0)
    assert a != generate_coalitions("pcp", "train", seed=1)
    assert a != generate_coalitions("pcp", "test", seed=0)


@pytest.mark.parametrize("task,split", sorted(CAPABILITY_RANGES))
def test_stored_files_equal_the_generator(task, split):
    path = COALITIONS_DIR / f"{task}_{split}.yaml"
    assert load_coalitions(path) == generate_coalitions(task, split, seed=0), f"{path} is stale: run `comat coalitions`"


def test_unseen_test_ranges_differ_from_training():
    # PCP test sensing radii reach below the training range; HMT test payloads beyond it.
    train = generate_coalitions("pcp", "train")
    test = generate_coalitions("pcp", "test")
    s_train = [r.capabilities[0] for t in train for r in t.robots if r.type == "sensing"]
    s_test = [r.capabilities[0] for t in test for r in t.robots if r.type == "sensing"]
    assert min(s_test) < min(s_train)


@pytest.mark.parametrize(
    "robots, match",
    [
        ((), r"needs at least one robot of each type \('sensing', 'capture'\), got an empty team"),
        ((RobotSpec("sensing", (0.4, 0.0)),), r"missing \['capture'\]"),
        ((RobotSpec("sensing", (0.4, 0.0)), RobotSpec("seeker", (0.0, 0.3))), r"robot 1: type must be one of"),
        (
            (RobotSpec("sensing", (1.5, 0.0)), RobotSpec("capture", (0.0, 0.3))),
            r"robot 0: sensing_radius_m must be in \[0.0, 1.0\] \(physical limit\), got 1.5",
        ),
        (
            (RobotSpec("sensing", (0.0, 0.0)), RobotSpec("capture", (0.0, 0.3))),
            r"robot 0: a sensing robot needs sensing_radius_m > 0, got 0.0",
        ),
        ((RobotSpec("sensing", (0.4,)), RobotSpec("capture", (0.0, 0.3))), r"robot 0: capabilities must be 2 numbers"),
        (
            (RobotSpec("sensing", (0.4, 0.3)), RobotSpec("capture", (0.0, 0.3))),
            r"robot 0: a sensing robot has no capture_radius_m \(the pcp rules ignore it\); expected 0, got 0.3",
        ),
        (
            (RobotSpec("sensing", (0.4, 0.0)), RobotSpec("capture", (0.2, 0.3))),
            r"robot 1: a capture robot has no sensing_radius_m",
        ),
    ],
)
def test_bad_teams(robots, match):
    with pytest.raises(ValueError, match=match):
        TeamSpec("pcp", robots)


def test_hmt_speed_limit_is_physical():
    with pytest.raises(ValueError, match=r"speed_m must be in \[0.0, 0.488\]"):
        TeamSpec("hmt", (RobotSpec("fast", (0.6, 5.0)), RobotSpec("slow", (0.1, 20.0))))


def test_round_trip_through_dict():
    team = generate_coalitions("hmt", "test")[3]
    assert TeamSpec.from_dict(team.to_dict()) == team
    np.testing.assert_array_equal(team.capability_array().shape, (team.size, 2))
