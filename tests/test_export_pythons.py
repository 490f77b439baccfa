"""Exports on the Robotarium server's Pythons (issue 66), and the duration they declare.

* Every file an export ships (each task's, both policies', the calibration folders', a generated
  ``submission_config.py``) parses as Python 3.8 and runs no PEP 585/604 expression at import or
  call (``tuple[int, int]``, ``int | None`` outside annotations), no Python >= 3.9 API and no numpy
  name that numpy 1.23.5 (the 3.8 server's) or 2.2.6 (the 3.10 server's) lacks; with pyenv's 3.8,
  ``py_compile`` under it too. ``make test-server`` runs the folders themselves under both.
* ``comat export`` prints ``declare N s and K robots`` and stores ``duration_s`` and ``robots``;
  ``--check`` warns when a run came within 10 % of ``duration_s``.
"""

from __future__ import annotations

import ast
import hashlib
import re
import subprocess
from pathlib import Path

import pytest

from comat import constants as C
from comat.cli.args import parse_team
from comat.tasks import task_entry, task_names
from sim2real.calibration import export_calibration
from sim2real.check import duration_warning, run_seconds
from sim2real.export import declared_duration_s, export_submission, load_config, shipped_code, startup_drive_s
from sim2real.server_pythons import SERVERS, ServerPythonError, find_python

BUILTIN_GENERICS = {"tuple", "list", "dict", "set", "frozenset", "type"}
"""Subscripted at run time (PEP 585) these raise TypeError on Python 3.8."""
BUILTIN_TYPES = BUILTIN_GENERICS | {"int", "float", "str", "bool", "bytes", "complex", "object"}
"""``X | Y`` of these at run time (PEP 604) raises TypeError before Python 3.10."""
NEWER_ATTRIBUTES = {"removeprefix": "3.9", "removesuffix": "3.9", "bit_count": "3.10", "pairwise": "3.10"}
"""Attributes (str, int, itertools) that Python 3.8 lacks, and the version that added them."""
NEWER_KEYWORDS = {("zip", "strict"): "3.10", ("dataclass", "slots"): "3.10", ("dataclass", "kw_only"): "3.10"}
"""Keyword arguments that Python 3.8 refuses (TypeError), by callee name."""
NEWER_IMPORTS = {("functools", "cache"): "3.9", ("math", "lcm"): "3.9", ("typing", "TypeAlias"): "3.10"}
"""Names that Python 3.8's standard library lacks."""
_NUMPY_AFTER_1_23 = """
acos acosh asin asinh astype atan atan2 atanh bitwise_count bitwise_invert bitwise_left_shift
bitwise_right_shift bool concat cumulative_prod cumulative_sum dtypes exceptions f2py isdtype long
matrix_transpose matvec permute_dims pow show_runtime strings trapezoid typing ulong unique_all unique_counts
unique_inverse unique_values unstack vecdot vecmat
"""
NUMPY_AFTER_1_23 = set(_NUMPY_AFTER_1_23.split())
"""Public numpy names of 2.2.6 (the 3.10 server's) that 1.23.5 (the 3.8 server's) lacks: ``dir(numpy)``
of both, diffed (2026-12-07)."""
_NUMPY_BEFORE_2 = """
ALLOW_THREADS AxisError BUFSIZE CLIP ComplexWarning DataSource ERR_CALL ERR_DEFAULT ERR_IGNORE ERR_LOG
ERR_PRINT ERR_RAISE ERR_WARN FLOATING_POINT_SUPPORT FPE_DIVIDEBYZERO FPE_INVALID FPE_OVERFLOW FPE_UNDERFLOW
Inf Infinity MAXDIMS MAY_SHARE_BOUNDS MAY_SHARE_EXACT ModuleDeprecationWarning NAN NINF NZERO NaN PINF PZERO
RAISE RankWarning SHIFT_DIVIDEBYZERO SHIFT_INVALID SHIFT_OVERFLOW SHIFT_UNDERFLOW Tester TooHardError
UFUNC_BUFSIZE_DEFAULT UFUNC_PYVALS_NAME VisibleDeprecationWarning WRAP add_docstring add_newdoc
add_newdoc_ufunc alltrue asfarray bool8 byte_bounds bytes0 cast cfloat chararray clongfloat compare_chararrays
compat complex_ cumproduct deprecate deprecate_with_doc disp fastCopyAndTranspose find_common_type float_
format_parser get_array_wrap geterrobj infty int0 issctype issubclass_ issubsctype kernel_version longcomplex
longfloat lookfor mat math matrixlib maximum_sctype msort nbytes numarray obj2sctype object0 oldnumeric os
product recfromcsv recfromtxt round_ safe_eval sctype2char sctypes set_numeric_ops set_string_function
seterrobj singlecomplex sometrue source str0 string_ sys tracemalloc_domain uint0 unicode_ use_hugepage
version void0 warnings who
"""
NUMPY_BEFORE_2 = set(_NUMPY_BEFORE_2.split())
"""Public numpy names of 1.23.5 that 2.2.6 lacks (the same diff)."""


# -- the static check ------------------------------------------------------------------------------
def _runtime_nodes(tree: ast.Module):
    """The nodes of ``tree`` that run when the module is imported or called. Annotations are left
    out only under ``from __future__ import annotations`` (which keeps them strings); without it a
    function's annotations are evaluated when it is defined."""
    lazy = any(
        isinstance(n, ast.ImportFrom) and n.module == "__future__" and any(a.name == "annotations" for a in n.names)
        for n in tree.body
    )
    skip = set()
    for node in ast.walk(tree) if lazy else ():
        if isinstance(node, ast.AnnAssign):
            skip.add(id(node.annotation))
        elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            args = [*node.args.posonlyargs, *node.args.args, *node.args.kwonlyargs, node.args.vararg, node.args.kwarg]
            skip.update(id(a.annotation) for a in args if a is not None and a.annotation is not None)
            if node.returns is not None:
                skip.add(id(node.returns))
    stack = [tree]
    while stack:
        node = stack.pop()
        if id(node) in skip:
            continue
        yield node
        stack.extend(ast.iter_child_nodes(node))


def _is_type_expr(node: ast.AST, abc_names: set[str]) -> bool:
    """``None``, a builtin type, a ``collections.abc`` name or a subscripted generic: what PEP 604's
    ``|`` joins (an array's ``a | b`` joins neither)."""
    if isinstance(node, ast.Constant) and node.value is None:
        return True
    if isinstance(node, ast.Name):
        return node.id in BUILTIN_TYPES or node.id in abc_names
    if isinstance(node, ast.Subscript):
        return _is_type_expr(node.value, abc_names)
    return isinstance(node, ast.BinOp) and isinstance(node.op, ast.BitOr)


def py38_problems(source: str, name: str = "<source>") -> list[str]:
    """What in ``source`` fails on Python 3.8 with numpy 1.23.5, or on 3.10 with numpy 2.2.6: ``line: what``."""
    try:
        ast.parse(source, feature_version=(3, 8))
    except SyntaxError as err:
        return [f"{err.lineno}: syntax Python 3.8 does not parse ({err.msg})"]
    tree = ast.parse(source)
    numpy_names = {"numpy"}
    abc_names = set()
    problems = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            numpy_names |= {a.asname or a.name for a in node.names if a.name == "numpy"}
        elif isinstance(node, ast.ImportFrom):
            if node.module == "collections.abc":
                abc_names |= {a.asname or a.name for a in node.names}
            for alias in node.names:
                if (node.module, alias.name) in NEWER_IMPORTS:
                    problems.append(
                        f"{node.lineno}: {node.module}.{alias.name} (Python {NEWER_IMPORTS[node.module, alias.name]})"
                    )
                if node.module == "numpy" and alias.name in NUMPY_AFTER_1_23 | NUMPY_BEFORE_2:
                    problems.append(f"{node.lineno}: numpy.{alias.name} (not in both numpy 1.23.5 and 2.2.6)")
    for node in _runtime_nodes(tree):
        line = getattr(node, "lineno", 0)
        if isinstance(node, ast.Subscript):
            base = node.value
            if (isinstance(base, ast.Name) and (base.id in BUILTIN_GENERICS or base.id in abc_names)) or (
                isinstance(base, ast.Attribute) and isinstance(base.value, ast.Name) and base.value.id == "abc"
            ):
                problems.append(f"{line}: {ast.unparse(node)} subscripted at run time (PEP 585, Python 3.9)")
        elif isinstance(node, ast.BinOp) and isinstance(node.op, ast.BitOr):
            if _is_type_expr(node.left, abc_names) and _is_type_expr(node.right, abc_names):
                problems.append(f"{line}: {ast.unparse(node)} at run time (PEP 604, Python 3.10)")
        elif isinstance(node, ast.Attribute):
            if node.attr in NEWER_ATTRIBUTES:
                problems.append(f"{line}: .{node.attr} (Python {NEWER_ATTRIBUTES[node.attr]})")
            if isinstance(node.value, ast.Name):
                if node.value.id in numpy_names and node.attr in NUMPY_AFTER_1_23 | NUMPY_BEFORE_2:
                    problems.append(f"{line}: {node.value.id}.{node.attr} (not in both numpy 1.23.5 and 2.2.6)")
                if (node.value.id, node.attr) in NEWER_IMPORTS:
                    problems.append(
                        f"{line}: {node.value.id}.{node.attr} (Python {NEWER_IMPORTS[node.value.id, node.attr]})"
                    )
        elif isinstance(node, ast.Call):
            callee = node.func.id if isinstance(node.func, ast.Name) else getattr(node.func, "attr", None)
            for kw in node.keywords:
                if (callee, kw.arg) in NEWER_KEYWORDS:
                    problems.append(f"{line}: {callee}({kw.arg}=...) (Python {NEWER_KEYWORDS[callee, kw.arg]})")
    return [f"{name}:{p}" for p in problems]


def _shipped(tmp: Path) -> dict[str, bytes]:
    """Every distinct .py file an export ships, under a readable name: each task's code for both
    policies, the calibration folders', and one generated submission_config.py."""
    files = {}
    for task in task_names():
        for policy in ("comat", "heuristic"):
            for name, code in shipped_code(task, policy).items():
                files.setdefault(hashlib.sha256(code).hexdigest(), (f"{task}/{name}", code))
    for folder in export_calibration(tmp / "calibration", 2):
        for path in folder.glob("*.py"):
            files.setdefault(
                hashlib.sha256(path.read_bytes()).hexdigest(),
                (f"calibration/{folder.name}/{path.name}", path.read_bytes()),
            )
    folder = export_submission("heuristic", "navigation", parse_team("test:3", "navigation"), tmp / "nav")
    files["config"] = ("navigation/submission_config.py", (folder / "submission_config.py").read_bytes())
    return dict(files.values())


@pytest.fixture(scope="module")
def shipped(tmp_path_factory):
    return _shipped(tmp_path_factory.mktemp("shipped"))


def test_every_shipped_file_runs_on_python_3_8_and_both_numpys(shipped):
    """The guide's server is Python 3.8 with numpy 1.23.5; V2's is 3.10 with numpy 2.2.6. An export
    ships task_logic.py, each task's module, main.py, the runtime, the loop, the log writer and its
    config; ``RGB = tuple[int, int, int]`` in task_logic.py once failed every export on 3.8."""
    assert {"pcp/main.py", "pcp/runtime.py", "pcp/task_logic.py", "navigation/submission_config.py"} <= set(shipped)
    assert {f"{t}/task_{t}.py" for t in task_names()} <= set(shipped)
    problems = [p for name, code in shipped.items() for p in py38_problems(code.decode(), name)]
    assert not problems, "\n".join(problems)


@pytest.mark.parametrize(
    "source, found",
    [
        ("RGB = tuple[int, int, int]\n", "PEP 585"),
        ("from collections.abc import Mapping\nM = Mapping[str, int]\n", "PEP 585"),
        ("def f(x):\n    return isinstance(x, int | str)\n", "PEP 604"),
        ("X = None | dict[str, int]\n", "PEP 604"),
        ("def f(x: int | None = None):\n    return x\n", "PEP 604"),  # no __future__: evaluated at def time
        ("import numpy as np\nx = np.concat([np.zeros(2)])\n", "numpy 1.23.5"),
        ("import numpy\nx = numpy.float_(1)\n", "numpy 1.23.5"),
        ("def f(a, b):\n    return list(zip(a, b, strict=True))\n", "zip(strict"),
        ("s = 'task_pcp'.removeprefix('task_')\n", "removeprefix"),
        ("from functools import cache\n", "functools.cache"),
        ("match 1:\n    case 1:\n        pass\n", "syntax Python 3.8"),
    ],
)
def test_the_check_finds_what_fails_on_python_3_8(source, found):
    problems = py38_problems(source)
    assert problems and found in problems[0], problems


def test_the_check_passes_what_runs_on_python_3_8():
    source = (
        "from __future__ import annotations\nimport numpy as np\n"
        "def f(a: np.ndarray, b: int | None = None) -> tuple[int, int]:\n"
        "    mask = (a > 0) | (a < -1)\n    x: dict[str, int] = {}\n    return mask.sum(), len(x)\n"
        "FLAGS = 1 | 2\n"
    )
    assert py38_problems(source) == []


def test_shipped_files_compile_under_pyenvs_python_3_8(shipped, tmp_path):
    try:
        python = find_python(SERVERS[0])
    except ServerPythonError as err:
        pytest.skip(f"no Python 3.8 here: {err}")
    paths = []
    for k, (name, code) in enumerate(sorted(shipped.items())):
        path = tmp_path / f"{k:03d}_{Path(name).name}"
        path.write_bytes(code)
        paths.append(str(path))
    proc = subprocess.run([python, "-m", "py_compile", *paths], capture_output=True, text=True, check=False)
    assert proc.returncode == 0, proc.stderr


# -- the duration to declare -----------------------------------------------------------------------
def test_find_python_names_what_is_missing(monkeypatch, tmp_path):
    monkeypatch.setenv("PYTHON38", str(tmp_path / "python3.8"))
    with pytest.raises(ServerPythonError, match=r"^PYTHON38='.*python3.8' is not a file \(expected a python3.8\)$"):
        find_python(SERVERS[0])
    fake = tmp_path / "python"
    fake.write_text("#!/bin/sh\necho 3.11\n")
    fake.chmod(0o755)
    monkeypatch.setenv("PYTHON38", str(fake))
    with pytest.raises(ServerPythonError, match=r"is Python 3.11, expected 3.8$"):
        find_python(SERVERS[0])


def test_declared_duration_counts_horizon_startup_drive_and_margin():
    # PCP: 80 steps x 29 ticks x 0.033 s = 76.56 s; 4 robots' drive bound 60 + 4 x 9 = 96 s; x 1.15 = 198.4
    assert startup_drive_s(4) == C.STARTUP_DRIVE_S + 4 * C.STARTUP_DRIVE_PER_ROBOT_S
    assert declared_duration_s(76.56, 4) == 200
    # HMT with 20 robots: 70 x 74 x 0.033 = 170.94 s + 240 s, x 1.15 = 472.6 -> 480
    assert declared_duration_s(170.94, 20) == 480
    assert declared_duration_s(170.94, 20) <= C.MAX_EXPERIMENT_S
    for n in (1, 8, 20):  # a run that uses its whole horizon and the whole bound stays out of the warning band
        full = 170.94 + startup_drive_s(n)
        assert full / declared_duration_s(170.94, n) < C.DURATION_WARN_SHARE


@pytest.mark.parametrize(
    "policy, task",
    [
        ("pretrained:comat-pcp", "pcp"),
        ("pretrained:comat-hmt", "hmt"),
        ("heuristic", "pcp"),
        ("heuristic", "warehouse"),
    ],
)
def test_export_prints_and_stores_the_duration_to_declare(policy, task, tmp_path, capsys):
    from comat.cli import main

    out = tmp_path / "sub"
    assert main(["export", "--policy", policy, "--task", task, "--team", "test:3", "--out", str(out)]) == 0
    config = load_config(out)
    logic = task_entry(task).logic()
    horizon_s = logic.horizon * logic.ticks_per_step * C.CONTROL_DT_S
    assert config["robots"] == len(config["types"]) and config["horizon_s"] == pytest.approx(horizon_s)
    assert config["duration_s"] == declared_duration_s(horizon_s, config["robots"])
    assert config["duration_s"] >= horizon_s + startup_drive_s(config["robots"])
    printed = re.findall(r"^declare (\d+) s and (\d+) robots \(", capsys.readouterr().out, re.MULTILINE)
    assert printed == [(str(config["duration_s"]), str(config["robots"]))]


def _with_duration(folder: Path, duration_s: int) -> None:
    path = folder / "submission_config.py"
    text, k = re.subn(r"'duration_s': \d+", f"'duration_s': {duration_s}", path.read_text())
    assert k == 1
    path.write_text(text)


def test_check_warns_when_a_run_came_within_10_percent_of_its_duration(tmp_path, capsys):
    """PCP's scripted policy on test:3 (4 robots) finishes in about 20 steps (600 iterations, 20 s),
    under the legacy rps, whose missing start-up drive counts as the folder's bound (96 s)."""
    from comat.cli import main

    out = tmp_path / "sub"
    assert (
        main(["export", "--policy", "heuristic", "--task", "pcp", "--team", "test:3", "--seed", "1", "--out", str(out)])
        == 0
    )
    capsys.readouterr()
    assert main(["export", "--check", str(out), "--tier", "unicycle"]) == 0
    assert "warning" not in capsys.readouterr().err  # about 115 s of the declared 200
    _with_duration(out, 120)
    assert main(["export", "--check", str(out), "--tier", "unicycle"]) == 0  # a warning, not a failure
    err = capsys.readouterr().err
    took = re.search(r"warning: .*sub: the run took (\d+) s of the 120 s the folder declares \((\d+) %", err)
    assert took, err
    assert C.DURATION_WARN_SHARE * 120 <= int(took[1]) and "declare more than 120 s" in err


def test_run_seconds_counts_the_drive_each_generation_has():
    config = {"duration_s": 200, "startup_drive_s": 96.0}
    legacy = {"rps": "legacy", "startup_iterations": 0, "iterations": 1537, "loop_wall_s": 9.0}
    v2 = {"rps": "v2", "startup_iterations": 3000, "iterations": 1537, "loop_wall_s": 9.0}
    assert run_seconds(config, legacy) == pytest.approx(96.0 + 1537 * 0.033)  # the bound for the testbed's drive
    assert run_seconds(config, v2) == pytest.approx((3000 + 1537) * 0.033)  # V2's own drive, simulated
    assert duration_warning(config, legacy) is None  # 147 s of 200
    assert duration_warning(config, v2) is None  # 150 s of 200
    long_drive = {**v2, "startup_iterations": 4500}  # a 149 s drive: 199 s of 200
    assert "start-up drive 148 s (bound 96 s)" in duration_warning(config, long_drive)
    slow = {**legacy, "loop_wall_s": 120.0}  # a loop slower than real time: 216 s of 200
    assert run_seconds(config, slow) == pytest.approx(216.0)
    assert "120 s of wall time here" in duration_warning(config, slow)
    under_layer = {**slow, "reality": {}}  # the layer's own cost is not the loop's
    assert run_seconds(config, under_layer) == pytest.approx(96.0 + 1537 * 0.033)
    assert duration_warning({"startup_drive_s": 96.0}, slow) is None  # exported before durations: nothing to hold
