"""A run's log: what an exported ``main.py`` saw and did, written while it runs and read back by comat.

Shipped verbatim in every export as ``run_log.py`` (numpy and the standard library only). A run
writes two real ``.npy`` files in its working folder, which the Robotarium returns with the run:

=======================  ==========================================================================
``comat_run.npy``        float32 (K, 3 + 8 N), one row per iteration of the loop, K growing while the
                         run goes: appended every :data:`FLUSH_EVERY` iterations (about 2 s) and at
                         the end, the ``.npy`` header rewritten after each append, so a run cut short
                         still returns every row flushed before (``np.load`` reads it)
``comat_run.meta.npy``   uint8, the UTF-8 bytes of a JSON object: written when the run starts (format,
                         version, comat version, task, policy and its weights' sha256, seed, team,
                         capabilities, start poses, prey, ticks per step, rps generation, filter,
                         :func:`columns`), and again at the end with ``result`` (the run's
                         COMAT_RESULT): a log without ``result`` is one of a run that did not finish
=======================  ==========================================================================

Columns of a row (:func:`columns`): ``t`` (s since the first iteration, the script's clock),
``iteration``, ``step`` (env steps done), then per robot i the pose the script received
``x_i, y_i, theta_i``, the unicycle command before the barrier ``v_nom_i, w_nom_i`` and as sent
``v_i, w_i`` (m/s, rad/s), and ``action_i``: the policy's action where this iteration starts an
env step, else -1.

Size: 8 float32 per robot and iteration plus 12 bytes: 58 kB per robot-minute at an iteration of
0.033 s (:func:`bytes_per_robot_minute`); a 20-robot HMT episode (70 steps of 74 iterations, 2.9 min)
is 3.4 MB.
"""

from __future__ import annotations

import json
import os

import numpy as np

__all__ = [
    "FLUSH_EVERY",
    "FORMAT",
    "LOG_FILE",
    "META_FILE",
    "VERSION",
    "RunLog",
    "RunLogError",
    "RunLogWriter",
    "bytes_per_robot_minute",
    "columns",
    "read_run_log",
]

FORMAT = "comat-run-log"
VERSION = 1
"""Bumped whenever the columns or the metadata change meaning; a reader refuses another version."""
LOG_FILE = "comat_run.npy"
META_FILE = "comat_run.meta.npy"
FLUSH_EVERY = 60
"""Iterations between appends to the log file (about 2 s at 0.033 s an iteration)."""
ITERATION_S = 0.033
"""The Robotarium's iteration (s), for the size figures."""

_MAGIC = b"\x93NUMPY\x01\x00"
_HEADER_BYTES = 128
"""The ``.npy`` header's fixed length: room for any row count, so it is rewritten in place."""
_PER_ROBOT = ("x", "y", "theta", "v_nom", "w_nom", "v", "w", "action")


def columns(n: int) -> list[str]:
    """The names of a row's 3 + 8 n columns for ``n`` robots."""
    return ["t", "iteration", "step"] + [f"{name}_{i}" for name in _PER_ROBOT for i in range(n)]


def bytes_per_robot_minute() -> float:
    """Bytes the log grows by per robot and minute of run (the three shared columns left out)."""
    return len(_PER_ROBOT) * 4 * 60.0 / ITERATION_S


def _header(rows: int, width: int) -> bytes:
    text = f"{{'descr': '<f4', 'fortran_order': False, 'shape': ({rows}, {width}), }}"
    text = text.ljust(_HEADER_BYTES - len(_MAGIC) - 2 - 1) + "\n"
    return _MAGIC + len(text).to_bytes(2, "little") + text.encode("latin1")


class RunLogWriter:
    """Writes a run's log in ``folder`` while the run goes (module docstring).

    Args:
        folder: where the two files go (the run's working folder on the Robotarium).
        meta: the run's facts (JSON-able); format, version and columns are added.
        n: robots.
    """

    def __init__(self, folder: str, meta: dict, n: int) -> None:
        self.folder, self.n, self.width = str(folder), int(n), 3 + 8 * int(n)
        os.makedirs(self.folder, exist_ok=True)
        self.meta = {"format": FORMAT, "version": VERSION, **meta, "robots": self.n, "columns": columns(self.n)}
        self._save_meta()
        self.path = os.path.join(self.folder, LOG_FILE)
        with open(self.path, "wb") as fh:
            fh.write(_header(0, self.width))
        self.rows, self._pending = 0, []

    def _save_meta(self) -> None:
        path = os.path.join(self.folder, META_FILE)
        data = np.frombuffer(json.dumps(self.meta).encode("utf-8"), dtype=np.uint8)
        np.save(path + ".tmp.npy", data)
        os.replace(path + ".tmp.npy", path)

    def write(self, t, iteration, step, poses, nominal, sent, actions=None) -> None:
        """One iteration: poses (3, N) received, commands (2, N) before the barrier and as sent,
        the policy's actions (N,) where an env step starts (else None)."""
        row = np.empty(self.width, dtype=np.float32)
        row[:3] = (t, iteration, step)
        n = self.n
        row[3 : 3 + 3 * n] = np.asarray(poses, dtype=float)[:3, :n].ravel()
        row[3 + 3 * n : 3 + 5 * n] = np.asarray(nominal, dtype=float)[:2, :n].ravel()
        row[3 + 5 * n : 3 + 7 * n] = np.asarray(sent, dtype=float)[:2, :n].ravel()
        row[3 + 7 * n :] = -1 if actions is None else np.asarray(actions)[:n]
        self._pending.append(row)
        if len(self._pending) >= FLUSH_EVERY:
            self.flush()

    def flush(self) -> None:
        """Append the pending rows, then rewrite the header (a reader never sees a row count the
        file does not hold)."""
        if not self._pending:
            return
        with open(self.path, "r+b") as fh:
            fh.seek(_HEADER_BYTES + 4 * self.width * self.rows)
            fh.write(np.stack(self._pending).astype("<f4").tobytes())
            fh.flush()
            self.rows += len(self._pending)
            fh.seek(0)
            fh.write(_header(self.rows, self.width))
        self._pending = []

    def finish(self, result: dict) -> None:
        """The last rows, and the metadata again with the run's result."""
        self.flush()
        self.meta["result"] = result
        self._save_meta()


class RunLogError(ValueError):
    """A log that cannot be read: names the file, what was expected and what it holds."""


class RunLog:
    """A run's log as read back: ``meta`` (dict), ``data`` float32 (K, 3 + 8 N), ``complete`` (the
    run finished: its metadata holds ``result``).

    Views (K rows): ``t`` (K,), ``step`` (K,), ``poses`` (K, N, 3), ``nominal`` and ``sent``
    (K, N, 2), ``actions`` (K, N) (-1 between step starts)."""

    def __init__(self, meta: dict, data: np.ndarray) -> None:
        self.meta, self.data, self.n = meta, data, int(meta["robots"])
        self.complete = "result" in meta

    def _block(self, first: int, size: int) -> np.ndarray:
        n = self.n
        return self.data[:, 3 + first * n : 3 + (first + size) * n].reshape(-1, size, n).transpose(0, 2, 1)

    @property
    def t(self) -> np.ndarray:
        return self.data[:, 0]

    @property
    def step(self) -> np.ndarray:
        return self.data[:, 2].astype(np.int64)

    @property
    def poses(self) -> np.ndarray:
        return self._block(0, 3)

    @property
    def nominal(self) -> np.ndarray:
        return self._block(3, 2)

    @property
    def sent(self) -> np.ndarray:
        return self._block(5, 2)

    @property
    def actions(self) -> np.ndarray:
        return self.data[:, 3 + 7 * self.n :].astype(np.int64)


def read_run_log(path: str) -> RunLog:
    """The log in folder ``path`` (or its ``comat_run.npy``); a run cut short reads as far as it was
    flushed (``complete`` False).

    Raises:
        RunLogError: a missing file, a file that is not a comat run log, a log of another format
            version, or rows that do not match the metadata (one line naming the file).
    """
    if not os.path.exists(path):
        raise RunLogError(f"{path}: no such file or folder (a run's log is {LOG_FILE} and {META_FILE}, side by side)")
    folder = path if os.path.isdir(path) else os.path.dirname(path) or "."
    log_path, meta_path = os.path.join(folder, LOG_FILE), os.path.join(folder, META_FILE)
    for p in (log_path, meta_path):
        if not os.path.isfile(p):
            raise RunLogError(f"{p}: no such file (a run's log is {LOG_FILE} and {META_FILE}, side by side)")
    try:
        meta = json.loads(np.load(meta_path).tobytes().decode("utf-8"))
    except (ValueError, UnicodeDecodeError, OSError) as err:
        raise RunLogError(f"{meta_path}: not a comat run log's metadata ({err})") from err
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        raise RunLogError(
            f"{meta_path}: expected format {FORMAT!r}, got {meta.get('format') if isinstance(meta, dict) else meta!r}"
        )
    if meta.get("version") != VERSION:
        raise RunLogError(
            f"{meta_path}: a log of format version {meta.get('version')!r} (comat {meta.get('comat', '?')}), "
            f"this comat reads version {VERSION}"
        )
    n = meta.get("robots")
    if not isinstance(n, int) or n < 1:
        raise RunLogError(f"{meta_path}: robots must be a positive integer, got {n!r}")
    try:
        data = np.load(log_path)
    except (ValueError, OSError, EOFError) as err:
        raise RunLogError(f"{log_path}: not a readable .npy file ({err})") from err
    if data.dtype != np.float32 or data.ndim != 2 or data.shape[1] != 3 + 8 * n:
        raise RunLogError(
            f"{log_path}: expected float32 rows of {3 + 8 * n} columns for {n} robots, got {data.dtype} {data.shape}"
        )
    if not np.isfinite(data[:, :3]).all() or (np.diff(data[:, 1]) != 1).any():
        raise RunLogError(f"{log_path}: iterations must count up by one from the first row: the rows are damaged")
    return RunLog(meta, data)
