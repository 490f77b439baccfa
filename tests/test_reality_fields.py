"""One source for every reality field: its declaration in :class:`comat.reality.RealityConfig`
holds its value at each level and its provenance; LEVELS, SOURCES, the docs table, the field
docstrings and the robustness sweeps agree with it."""

from __future__ import annotations

import ast
import dataclasses
import inspect
import itertools
import re

import pytest

from comat.reality import LEVELS, REALITY_LEVELS, SOURCES, RealityConfig
from comat.reality import config as reality_config

FIELDS = [f for f in dataclasses.fields(RealityConfig) if f.name != "level"]


def _docstrings() -> dict[str, str]:
    """Each RealityConfig field's docstring (the string literal right after its declaration)."""
    body = ast.parse(inspect.getsource(RealityConfig)).body[0].body
    out = {}
    for stmt, after in itertools.pairwise(body):
        docstring = isinstance(after, ast.Expr) and isinstance(after.value, ast.Constant)
        if isinstance(stmt, ast.AnnAssign) and docstring:
            out[stmt.target.id] = " ".join(after.value.value.split())
    del out["level"]
    return out


def test_levels_and_sources_are_the_declarations():
    for f in FIELDS:
        meta = f.metadata
        assert f.default is None, f.name  # None: the level's value
        assert set(meta["levels"]) == set(REALITY_LEVELS), f.name
        assert meta["mark"] in reality_config.MARKS and meta["source"], f.name
        assert SOURCES[f.name] == (meta["mark"], meta["source"])
        for level in REALITY_LEVELS:
            assert LEVELS[level][f.name] is meta["levels"][level]
    assert list(LEVELS["off"]) == [f.name for f in FIELDS] == list(SOURCES)
    for level in REALITY_LEVELS:  # every level is a valid config that resolves to its declared values
        assert {k: getattr(RealityConfig(level=level), k) for k in LEVELS[level]} == LEVELS[level]
    assert RealityConfig(level="off").is_off and not RealityConfig(level="nominal").is_off


def test_a_field_is_declared_with_a_known_mark():
    with pytest.raises(ValueError, match="mark must be one of"):
        reality_config._field(0, 0, 0, "guessed", "—")


_NUMBER = r"(-?\d+(?:\.\d+)?)"


def test_field_docstrings_do_not_contradict_the_declared_values():
    """A docstring says what a field is and why; a level value it names must be the declared one."""
    docs = _docstrings()
    assert set(docs) == {f.name for f in FIELDS}, "every field has a docstring"
    for name, doc in docs.items():
        for level in ("nominal", "stress"):
            for m in re.finditer(rf"\b{level} {_NUMBER}\b(?! ?[%a-zA-Z°/])", doc):
                assert float(m.group(1)) == LEVELS[level][name], f"{name}: docstring says {m.group(0)!r}"
        for m in re.finditer(rf"{_NUMBER} (?:at both|at every|at all) levels", doc):
            value = float(m.group(1))
            assert value == LEVELS["nominal"][name] == LEVELS["stress"][name], f"{name}: {m.group(0)!r}"


def test_the_robustness_sweeps_run_valid_values_through_every_level():
    """Each default sweep is of a numeric field, every value of it makes a valid config, and it
    passes through the field's off, nominal and stress values (its docstring's promise)."""
    from comat.eval.robustness import SWEEP_VALUES, sweep_values

    for component, grid in SWEEP_VALUES.items():
        values = sweep_values(component, None)
        assert len(values) == len(grid) >= 3
        for v in values:
            RealityConfig(**{component: v})  # base off: the component alone
        for level in REALITY_LEVELS:
            assert LEVELS[level][component] in values, f"{component}: the {level} value is not swept"
