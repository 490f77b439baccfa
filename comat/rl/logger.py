"""What a training run records: CSV tables, TensorBoard scalars and a progress line.

``progress.csv`` has one row per update, ``eval.csv`` one row per evaluation; both keyed by
``env_steps``. On resume, rows written after the checkpoint being resumed are dropped (from
the CSV files, and from TensorBoard with ``purge_step``), so a resumed run's logs read like an
uninterrupted one's.
"""

from __future__ import annotations

import csv
import math
import sys
import time
from pathlib import Path

from comat.measure.metrics import RETIRED_NAMES

__all__ = ["ExpectedTime", "ProgressLine", "RunLogger"]


def _truncate_csv(path: Path, max_step: int) -> None:
    if not path.exists():
        return
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    if not rows:
        return
    header, body = rows[0], rows[1:]
    col = header.index("env_steps")
    keep = [r for r in body if r and float(r[col]) <= max_step]
    with open(path, "w", newline="") as fh:
        csv.writer(fh).writerows([header, *keep])


class RunLogger:
    """Appends rows to ``<out>/<table>.csv`` and scalars to TensorBoard under ``<out>/tb``.

    Args:
        out: the run folder.
        resume_step: env steps of the checkpoint being resumed (None for a new run).
        tensorboard: write TensorBoard events.
    """

    def __init__(self, out: Path, resume_step: int | None = None, tensorboard: bool = True) -> None:
        self.out = Path(out)
        self._headers: dict[str, list[str]] = {}
        tables = ("progress", "eval", *(p.stem for p in sorted(self.out.glob("eval_*.csv"))))
        if resume_step is not None:
            for table in tables:
                _truncate_csv(self.out / f"{table}.csv", resume_step)
        for table in tables:
            path = self.out / f"{table}.csv"
            if path.exists() and path.stat().st_size:
                with open(path, newline="") as fh:
                    rows = list(csv.reader(fh))
                header = [RETIRED_NAMES.get(name, name) for name in rows[0]]
                if header != rows[0]:  # a run started before issue 32's names: resume under today's
                    with open(path, "w", newline="") as fh:
                        csv.writer(fh).writerows([header, *rows[1:]])
                self._headers[table] = header
        self._tb = None
        if tensorboard:
            from torch.utils.tensorboard import SummaryWriter

            purge = None if resume_step is None else resume_step + 1
            self._tb = SummaryWriter(str(self.out / "tb"), purge_step=purge)

    def log(self, table: str, env_steps: int, values: dict[str, float]) -> None:
        """One row of ``table`` ("progress", "eval" or "eval_SET") at ``env_steps``."""
        row = {"env_steps": env_steps, **values}
        path = self.out / f"{table}.csv"
        header = self._headers.get(table)
        if header is None:
            header = self._headers[table] = list(row)
            with open(path, "w", newline="") as fh:
                csv.writer(fh).writerow(header)
        with open(path, "a", newline="") as fh:
            csv.writer(fh).writerow([row.get(k, "") for k in header])
        if self._tb is not None:
            for key, value in values.items():
                if isinstance(value, (int, float)) and math.isfinite(value):
                    self._tb.add_scalar(f"{table}/{key}", value, env_steps)

    def close(self) -> None:
        if self._tb is not None:
            self._tb.close()


def _clock(seconds: float) -> str:
    if not math.isfinite(seconds):
        return "?"
    s = int(seconds)
    return f"{s // 3600}:{s // 60 % 60:02d}:{s % 60:02d}"


class ProgressLine:
    """``[####------] 12,800/100,000 steps | 410 steps/s | return 12.3 | finished 21% (progress 41%) | ETA 0:03:57``.

    Redrawn in place on a terminal; elsewhere (logs, CI) printed at most every ``every_s``.
    """

    def __init__(self, total: int, start: int = 0, stream=None, every_s: float = 30.0) -> None:
        self.total, self.start = total, start
        self.stream = stream or sys.stderr
        self.tty = self.stream.isatty()
        self.every_s = every_s
        self._t0 = time.perf_counter()
        self._last_print = -math.inf

    def update(self, steps: int, ret: float, finished: float, progress: float, final: bool = False) -> None:
        """``finished``: share of recent episodes that finished the task (the paper's
        "completion"); ``progress``: their mean fraction of prey captured / material delivered."""
        elapsed = time.perf_counter() - self._t0
        rate = (steps - self.start) / elapsed if elapsed > 0 else 0.0
        eta = max(self.total - steps, 0) / rate if rate > 0 else math.inf  # the last rollout may overshoot
        frac = min(1.0, steps / self.total)
        bar = "#" * int(20 * frac) + "-" * (20 - int(20 * frac))
        line = (
            f"[{bar}] {steps:,}/{self.total:,} steps | {rate:,.0f} steps/s | return {ret:.2f} | "
            f"finished {finished:.0%} (progress {progress:.0%}) | ETA {_clock(eta)}"
        )
        if self.tty:
            self.stream.write("\r" + line + ("\n" if final else ""))
            self.stream.flush()
        elif final or elapsed - self._last_print >= self.every_s:
            self.stream.write(line + "\n")
            self.stream.flush()
            self._last_print = elapsed


class ExpectedTime:
    """The run's expected wall time from its first updates, said once: ``expected(...)`` returns the
    line after :attr:`TIMED` updates past the first (the first pays for set-ups and compilation,
    and would overstate the rest), else None.

    The figure is training alone (collecting and learning); each evaluation adds its own time."""

    TIMED = 2

    def __init__(self, total: int, start: int, workers: int, threads: int, overlap: bool = False) -> None:
        self.total, self.start, self.workers, self.threads = total, start, workers, threads
        self.overlap = overlap
        self._seen, self._steps, self._seconds, self._said = 0, 0, 0.0, False

    def expected(self, steps: int, n: int, dt: float, elapsed: float) -> str | None:
        """After an update of ``n`` env steps that took ``dt`` s, ``steps`` done and ``elapsed`` s since
        the run (or its resumption) started."""
        self._seen += 1
        if self._said or self._seen == 1:
            return None
        self._steps, self._seconds = self._steps + n, self._seconds + dt
        if self._seen <= self.TIMED:
            return None
        self._said = True
        rate = self._steps / self._seconds
        left = max(self.total - steps, 0) / rate
        return (
            f"expected: {_clock(elapsed + left)} for {self.total - self.start:,} env steps "
            f"({rate:,.0f} env-steps/s over updates 2-{self._seen}, {self.workers} env worker(s), "
            f"{self.threads} learner thread(s){', collecting beside the update' if self.overlap else ''}; "
            "evaluations add their own time; docs/speed.md)"
        )
