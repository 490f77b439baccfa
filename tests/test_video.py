"""Videos of rollouts (comat rollout --video): decoded back, frame count and size checked."""

import imageio.v3 as iio
import numpy as np
import pytest

from comat.cli import main
from comat.envs.render import FRAME_SIZE
from comat.viz import record_episodes
from comat.viz.video import VideoWriter


@pytest.mark.parametrize("suffix", [".mp4", ".gif"])
def test_rollout_video_decodes_to_one_frame_per_step(tmp_path, capsys, suffix):
    video = tmp_path / f"run{suffix}"
    code = main(
        [
            "rollout",
            "--task",
            "pcp",
            "--policy",
            "heuristic",
            "--episodes",
            "2",
            "--tier",
            "unicycle",
            "--video",
            str(video),
        ]
    )
    assert code == 0
    printed = capsys.readouterr().out
    steps = [int(line.split(" steps")[0].split()[-1]) for line in printed.splitlines() if "episode " in line]
    assert len(steps) == 2
    frames = iio.imread(video, index=None)
    # one frame at each episode's start and one per env step, every one the frame size
    assert frames.shape == (sum(steps) + 2, *FRAME_SIZE, 3) and frames.dtype == np.uint8
    assert f"{sum(steps) + 2} frames at 10 fps" in printed
    assert not list(tmp_path.glob("*.rrd")) and not list(tmp_path.glob(".*"))  # video alone, no temporary left


def test_video_frames_are_the_env_render_frames(tmp_path):
    import comat

    result = record_episodes(None, "hmt", "heuristic", episodes=1, tier="unicycle", video=tmp_path / "x.gif", seed=4)
    decoded = iio.imread(result.video, index=None)
    env = comat.make_env("hmt_v0", coalitions="train", tier="unicycle", render_mode="rgb_array")
    env.reset(seed=4)
    first = env.render()
    assert decoded.shape[0] == int(result.episodes[0]["steps"]) + 1
    # a 64-colour GIF of the same drawing (the caption line aside): close to the frame, pixel for pixel
    body = slice(48, None)
    assert np.abs(decoded[0, body].astype(int) - first[body].astype(int)).mean() < 6


def test_bad_videos_are_refused_and_leave_nothing(tmp_path, capsys):
    assert main(["rollout", "--task", "pcp", "--video", str(tmp_path / "x.avi")]) == 2
    assert "video must be a file name ending in .mp4 or .gif, got" in capsys.readouterr().err
    with (
        pytest.raises(ValueError, match="frame must be an \\(H, W, 3\\) uint8 array"),
        VideoWriter(tmp_path / "y.mp4") as w,
    ):
        w.append(np.zeros((4, 4)))
    with pytest.raises(RuntimeError, match="boom"), VideoWriter(tmp_path / "z.gif") as w:
        w.append(np.zeros((*FRAME_SIZE, 3), np.uint8))
        raise RuntimeError("boom")
    assert list(tmp_path.iterdir()) == []  # neither the videos nor their temporary files


def test_a_shipped_policys_caption_fits_beside_the_coordination_metric(monkeypatch):
    """The header's first line of `comat rollout --policy pretrained:comat-pcp` (one episode, a
    4-robot team, the default seed) is drawn whole, not cut with "…" (newcomer minor)."""
    import comat
    from comat.envs import render
    from comat.viz.rollout import frame_caption

    drawn = []
    real = render._shorten

    def shorten(text, end_px, renderer):
        real(text, end_px, renderer)
        drawn.append(text.get_text())

    monkeypatch.setattr(render, "_shorten", shorten)
    env = comat.make_env("pcp_v0", coalitions="test", tier="unicycle", render_mode="rgb_array")
    env.reset(seed=2_000_003)
    env.step({a: 0 for a in env.agents})  # the coordination metric shows from the first step on
    env.render_caption = caption = frame_caption("pretrained:comat-pcp", 4, 2_000_003, 0, 1)
    env.render()
    assert drawn == [caption] and "episode" not in caption
    assert frame_caption("p", 4, 7, 1, 2) == "p · 4 robots · seed 7 · episode 1"
