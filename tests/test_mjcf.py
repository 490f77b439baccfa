from pathlib import Path

import mujoco
import numpy as np
import pytest

from comat import constants as C
from comat.mjcf import arena_spec, robot_spec, scene_spec, write_assets
from comat.mjcf.scene import GOLDEN_TEAM_SIZES, physics_timestep

ASSETS = Path(__file__).resolve().parents[1] / "assets" / "mjcf"


def test_golden_files_match_the_generator(tmp_path):
    written = write_assets(tmp_path)
    assert {p.name for p in written} == {p.name for p in ASSETS.glob("*.xml")}, (
        "assets/mjcf is out of date: run `comat mjcf --out assets/mjcf`"
    )
    for path in written:
        assert path.read_text() == (ASSETS / path.name).read_text(), f"{path.name} differs from the generator"


@pytest.mark.parametrize("tier", ["wheels", "unicycle"])
@pytest.mark.parametrize("n", GOLDEN_TEAM_SIZES)
def test_golden_scenes_load_and_match_counts(tier, n):
    model = mujoco.MjModel.from_xml_path(str(ASSETS / f"scene_{tier}_n{n}.xml"))
    per_robot = {"wheels": {"nq": 9, "nu": 2, "nbody": 3}, "unicycle": {"nq": 3, "nu": 3, "nbody": 1}}[tier]
    assert model.nq == n * per_robot["nq"]
    assert model.nu == n * per_robot["nu"]
    assert model.nbody == 2 + n * per_robot["nbody"]  # world + walls + robots
    assert model.nsensor == 2 * n
    assert model.nkey == 1
    compiled = scene_spec(n, tier).compile()
    assert (model.nq, model.nv, model.nu, model.ngeom) == (compiled.nq, compiled.nv, compiled.nu, compiled.ngeom)


@pytest.mark.parametrize("tier", ["wheels", "unicycle"])
def test_every_element_is_named_and_prefixed(tier):
    model = scene_spec(3, tier).compile()
    for kind, count in (
        ("geom", model.ngeom),
        ("body", model.nbody),
        ("joint", model.njnt),
        ("actuator", model.nu),
        ("site", model.nsite),
        ("sensor", model.nsensor),
    ):
        for i in range(count):
            name = getattr(model, kind)(i).name
            if kind == "body" and i == 0:
                continue
            assert name, f"unnamed {kind} {i}"
    for i in range(3):
        assert model.body(f"robot_{i}/chassis").id > 0
        assert model.site(f"robot_{i}/projection_point").id >= 0


@pytest.mark.parametrize("tier", ["wheels", "unicycle"])
def test_collision_bits_allow_robot_robot_and_robot_wall_contacts_only(tier):
    model = scene_spec(2, tier).compile()

    def collide(a, b):
        ga, gb = model.geom(a).id, model.geom(b).id
        return bool(
            model.geom_contype[ga] & model.geom_conaffinity[gb] or model.geom_contype[gb] & model.geom_conaffinity[ga]
        )

    assert collide("robot_0/chassis", "robot_1/chassis")
    assert collide("robot_0/chassis", "wall_east")
    assert not collide("robot_0/chassis", "floor")
    if tier == "wheels":
        assert collide("robot_0/left_wheel", "floor") and collide("robot_0/front_caster", "floor")
        assert not collide("robot_0/left_wheel", "wall_east")
        assert not collide("robot_0/left_wheel", "robot_1/chassis")
    else:
        assert not collide("robot_0/left_wheel", "floor")


def test_arena_walls_sit_on_the_boundary():
    model = arena_spec().compile()
    _x0, x1, _y0, y1 = C.ARENA_BOUNDS_M
    east = model.geom("wall_east")
    assert east.pos[0] - east.size[0] == pytest.approx(x1)
    north = model.geom("wall_north")
    assert north.pos[1] - north.size[1] == pytest.approx(y1)
    assert model.site("zone/hmt_dropoff").id >= 0


def test_robot_geometry_follows_the_profile():
    for profile in C.PROFILES.values():
        model = robot_spec("wheels", profile).compile()
        left = model.body("left_wheel").pos
        right = model.body("right_wheel").pos
        assert left[1] - right[1] == pytest.approx(profile.base_length_m)
        assert model.geom("left_wheel").size[0] == pytest.approx(profile.wheel_radius_m)
        assert model.geom("chassis").size[0] == pytest.approx(profile.radius_m)
        np.testing.assert_allclose(model.actuator_ctrlrange[0], [-12.5, 12.5])


def test_timestep_divides_the_tick():
    assert physics_timestep(4) * 4 == pytest.approx(C.CONTROL_DT_S)
    with pytest.raises(ValueError, match="substeps must be a positive integer, got 0"):
        physics_timestep(0)


def test_bad_scene_arguments():
    with pytest.raises(ValueError, match="n_robots must be a positive integer, got 0"):
        scene_spec(0)
    with pytest.raises(ValueError, match=r"tier must be one of \('wheels', 'unicycle'\), got 'legs'"):
        scene_spec(2, "legs")
