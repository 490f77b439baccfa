"""The training progress line and the run's expected wall time (comat.rl.logger)."""

import io

from comat.rl.logger import ExpectedTime, ProgressLine


def test_progress_line_eta_never_negative():
    out = io.StringIO()
    line = ProgressLine(total=1000, stream=out)
    line.update(400, 1.0, 0.0, 0.5)
    line.update(1024, 2.0, 0.5, 0.9, final=True)  # the last rollout overshoots the budget
    assert out.getvalue().rstrip().endswith("ETA 0:00:00")
    assert "1,024/1,000 steps" in out.getvalue()


def test_the_expected_wall_time_is_said_once_from_the_updates_after_the_first():
    clock = ExpectedTime(total=100_000, start=0, workers=2, threads=2)
    # the first update (set-ups, compilation) is slow and left out: 2,560 steps in 30 s, then 2,560 in 5 s
    said = [clock.expected(2560 * k, 2560, 30.0 if k == 1 else 5.0, 30.0 + 5.0 * (k - 1)) for k in (1, 2, 3, 4)]
    assert said[0] is None and said[1] is None and said[3] is None
    # 512 env-steps/s: 40 s done, 92,320 left -> 180.3 s more = 0:03:40 in all
    assert said[2].startswith("expected: 0:03:40 for 100,000 env steps (512 env-steps/s over updates 2-3")
    assert "learner thread(s); evaluations" in said[2]
    overlapped = ExpectedTime(total=100_000, start=0, workers=2, threads=2, overlap=True)
    said = [overlapped.expected(2560 * k, 2560, 5.0, 5.0 * k) for k in (1, 2, 3)][2]
    assert "2 learner thread(s), collecting beside the update; evaluations" in said
