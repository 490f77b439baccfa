"""The reality layer in recordings, videos and the demo (issue 29 part 4): measured poses next to
true ones, faults marked; nothing of it at off."""

import numpy as np
from test_viz import column, read

from comat.envs.render import EpisodeFrames
from comat.viz import record_episodes


def test_recording_holds_measured_poses_error_lines_and_faults(tmp_path):
    reality = {"level": "stress", "fault_prob": 1.0, "fault_start_max_s": 0.5}
    out = tmp_path / "r.rrd"
    result = record_episodes(
        out,
        "pcp",
        "heuristic",
        episodes=1,
        coalitions="test",
        seed=2,
        tier="unicycle",
        ticks_per_step=6,
        reality=reality,
    )
    static, temporal = read(out)
    steps = int(result.episodes[0]["steps"])
    true = column(temporal["/episode_0/world/robots"], "Points2D:positions")
    seen = column(temporal["/episode_0/world/robots/measured"], "Points2D:positions")
    assert len(seen) == len(true) == steps + 1
    err = max(np.abs(np.asarray(a) - np.asarray(b)).max() for a, b in zip(true, seen))
    assert 1e-4 < err < 0.5  # measured poses differ from the true ones, by noise and delay
    lines = temporal["/episode_0/world/robots/pose_error"]
    assert lines.num_rows == steps + 1
    faults = column(temporal["/episode_0/world/robots/fault"], "Points2D:positions")
    assert sum(len(f) for f in faults[-3:]) == 3  # one robot faulty from 0.5 s on, every step at the end
    assert "stress" not in str(static["/episode_0/meta"])  # the level is named custom: fields changed
    assert "custom" in str(static["/episode_0/meta"])


def test_off_recordings_have_no_reality_entities(tmp_path):
    out = tmp_path / "o.rrd"
    record_episodes(out, "hmt", "heuristic", episodes=1, coalitions="test", seed=2, tier="unicycle", ticks_per_step=6)
    _, temporal = read(out)
    assert not [k for k in temporal if "measured" in k or "pose_error" in k or "fault" in k]


def test_video_frames_draw_the_ghost_only_under_the_layer():
    import comat

    frames = {}
    for level in ("off", {"pose_bias_xy_m": 0.05}):
        env = comat.make_env("pcp_v0", coalitions="test", tier="unicycle", ticks_per_step=6, reality=level)
        env.reset(seed=1)
        follower = EpisodeFrames()
        follower.begin(env.core, 0)
        frames[str(level)] = follower.frame()
        follower.close()
    a, b = frames.values()
    assert a.shape == b.shape and (a != b).any()  # a bias of 5 cm is a visible ghost


def test_training_recordings_play_at_the_runs_level(tmp_path):
    from test_rl import tiny

    from comat.rl import train
    from comat.viz import record_training

    config = tiny("comat", steps=6, eval_every_steps=6, eval_episodes_per_team=1, reality="nominal")
    train(config, tmp_path / "run", quiet=True, rrd_every=1, record=record_training)
    (path,) = (tmp_path / "run" / "rrd").glob("*.rrd")
    static, temporal = read(path)
    assert "/episode_0/world/robots/measured" in temporal and "nominal" in str(static["/episode_0/meta"])
