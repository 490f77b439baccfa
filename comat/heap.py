"""Handing freed heap memory back to the operating system (glibc's ``malloc_trim``).

Why: a batch of episodes has moments of high transient allocation (OSQP problems of many teams
at once, MuJoCo and numpy scratch arrays); when they are freed, glibc keeps the pages resident
unless they sit at the top of its heap. Resident memory then ratchets up with each new peak
without anything being leaked: in a soak over U_train, U_test and U_scale (12 vector envs in one
process) it rose 336 -> 353 MiB over the first 2,400 episodes in steps at single batches, with a
fixed mmap threshold or a single malloc arena exactly as much, while trimming after every round
kept it at 285-318 MiB. (With a trim at every env reset the 10,080-episode soak still rose
301 -> 338 MiB while idle envs held their last batch's OSQP problems; with those dropped after
every batch, :meth:`comat.envs.VectorEnv.release_solvers`, 264 -> 271 MiB: docs/safety.md, "Reliability".)
:class:`comat.envs.vector.VectorEnv` calls
:func:`release_free_heap` on every full reset (the start of each evaluation batch); it costs a
few milliseconds.
"""

from __future__ import annotations

import ctypes
import functools
import sys

__all__ = ["release_free_heap"]


@functools.cache
def _trim():
    """glibc's malloc_trim, or None where there is none (other platforms and C libraries)."""
    if not sys.platform.startswith("linux"):
        return None
    try:
        return ctypes.CDLL("libc.so.6").malloc_trim
    except (OSError, AttributeError):
        return None


def release_free_heap() -> bool:
    """Return the free pages of the heap to the OS; False where this C library cannot."""
    trim = _trim()
    if trim is None:
        return False
    trim(0)
    return True
