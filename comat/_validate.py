"""Input checks for public boundaries: each error names the argument, the expectation and the value."""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["as_float_array", "check_choice", "check_positive_int"]


def _describe(value: Any) -> str:
    if isinstance(value, np.ndarray):
        return f"array of shape {value.shape} and dtype {value.dtype}"
    return repr(value)


def as_float_array(name: str, value: Any, shape: tuple[int | str, ...], finite: bool = True) -> np.ndarray:
    """Return ``value`` as a float64 array of ``shape``, or raise.

    ``shape`` entries are exact lengths (int) or symbolic names of free lengths (``"N"``).

    Raises:
        TypeError: not convertible to a float array.
        ValueError: wrong shape, or NaN/inf entries when ``finite``.
    """
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"{name} must be a float array of shape {_fmt(shape)}, got {_describe(value)}") from exc
    if arr.ndim != len(shape) or any(isinstance(s, int) and s != a for s, a in zip(shape, arr.shape)):
        raise ValueError(f"{name} must have shape {_fmt(shape)}, got shape {arr.shape}")
    if finite and not np.all(np.isfinite(arr)):
        bad = np.argwhere(~np.isfinite(arr))[0]
        raise ValueError(f"{name} must be finite, got {arr[tuple(bad)]} at index {tuple(int(i) for i in bad)}")
    return arr


def check_positive_int(name: str, value: Any) -> int:
    """Return ``value`` as int if it is a positive integer (bools excluded), else raise ValueError."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise ValueError(f"{name} must be a positive integer, got {value!r}")
    return int(value)


def check_choice(name: str, value: Any, choices: tuple[str, ...]) -> str:
    """Return ``value`` if it is one of ``choices``, else raise ValueError listing them."""
    if value not in choices:
        raise ValueError(f"{name} must be one of {choices}, got {value!r}")
    return value


def _fmt(shape: tuple[int | str, ...]) -> str:
    return "(" + ", ".join(str(s) for s in shape) + ("," if len(shape) == 1 else "") + ")"
