"""The faces of comat.rl, comat.eval, comat.models and comat.bench (issue 67): each ``__init__``
exports what callers outside it use, loads it on first use, and an import-linter contract a
package fails on a deep import from outside it (planted in a copy of the tree)."""

from __future__ import annotations

import importlib
import importlib.util
import os
import pkgutil
import shutil
import subprocess
import sys
import types
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
FACES = ("comat.rl", "comat.eval", "comat.models", "comat.bench")
LINT_IMPORTS = [sys.executable, "-c", "import sys, importlinter.cli as c; sys.exit(c.lint_imports_command())"]
HAS_IMPORTLINTER = importlib.util.find_spec("importlinter") is not None


@pytest.mark.parametrize("package", FACES)
def test_every_name_of_a_face_is_its_package_s_own(package):
    face = importlib.import_module(package)
    submodules = {m.name for m in pkgutil.iter_modules(face.__path__)}
    assert face.__all__ == sorted(face.__all__) and set(face.__all__) <= set(dir(face))
    # a name that is also a submodule's would turn into that module once the submodule loads
    assert not submodules & set(face.__all__)
    for name in face.__all__:
        value = getattr(face, name)
        home = getattr(value, "__module__", None)
        if callable(value) and home is not None:  # classes and functions: defined in the package
            assert home.startswith(package + "."), (name, home)
    with pytest.raises(AttributeError, match=f"module '{package}' has no attribute 'nope'"):
        face.nope  # noqa: B018 - the look-up is the test


def test_the_renamed_replay_stays_the_function_after_its_module_loads():
    import comat.eval
    import comat.eval.replay

    assert isinstance(comat.eval.replay, types.ModuleType)  # as the import system binds it on the package
    from comat.eval import replay_log

    assert replay_log is comat.eval.replay.replay and callable(replay_log)


def test_a_patch_of_the_home_module_is_seen_through_the_face(monkeypatch):
    import comat.rl
    import comat.rl.runner

    def fake(*args, **kwargs):
        return None

    monkeypatch.setattr(comat.rl.runner, "train", fake)
    assert comat.rl.train is fake  # nothing cached on the package: tests patch comat.rl.runner.train


def test_importing_the_faces_loads_neither_torch_nor_their_modules():
    code = (
        "import sys, comat.rl, comat.eval, comat.models, comat.bench, sim2real\n"
        "from comat.models import DECISIONS\n"
        "from comat.bench import SCENARIO_NAMES\n"
        "heavy = sorted(m for m in sys.modules if m.split('.')[0] == 'torch' or m in "
        "('comat.rl.ppo', 'comat.eval.evaluate', 'comat.models.comat', 'comat.bench.learn_bench'))\n"
        "assert not heavy, heavy\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True, cwd=ROOT)


def _lint_imports(root: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(root)}
    return subprocess.run([*LINT_IMPORTS, "--no-cache"], cwd=root, env=env, capture_output=True, text=True, check=False)


@pytest.mark.skipif(not HAS_IMPORTLINTER, reason="import-linter is in the lint extra")
def test_the_tree_keeps_the_face_contracts_and_a_planted_deep_import_breaks_them(tmp_path):
    for package in ("comat", "sim2real"):
        for path in (ROOT / package).rglob("*.py"):
            (tmp_path / path.relative_to(ROOT)).parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(path, tmp_path / path.relative_to(ROOT))
    shutil.copyfile(ROOT / "pyproject.toml", tmp_path / "pyproject.toml")
    kept = _lint_imports(tmp_path)
    assert kept.returncode == 0 and "0 broken" in kept.stdout, kept.stdout + kept.stderr

    planted = {
        "comat/cli/_planted.py": "from comat.rl.ppo import PPOTrainer\nfrom comat.eval.evaluate import EVAL_SEED\n"
        "from comat.models.layers import mlp\nfrom comat.bench.scenarios import SCENARIOS\n"
        "from comat.rl import PPOTrainer as ThroughTheFace\n",
        # sim2real and sim2real.export may name comat_schema (they copy its file); another module may not
        "sim2real/_planted.py": "from comat.models.comat_schema import DECISIONS\n",
    }
    for name, text in planted.items():
        (tmp_path / name).write_text(text)
    broken = _lint_imports(tmp_path)
    out = " ".join(broken.stdout.split())  # the report wraps long lines
    assert broken.returncode == 1 and "3 kept, 4 broken" in out, out
    for link in (
        "comat.cli._planted -> comat.rl.ppo",
        "comat.cli._planted -> comat.eval.evaluate",
        "comat.cli._planted -> comat.models.layers",
        "comat.cli._planted -> comat.bench.scenarios",
        "sim2real._planted -> comat.models.comat_schema",
    ):
        assert link in out, (link, out)
    assert "-> comat.rl (l." not in out  # the import through the face is not one of them


def test_a_name_listed_twice_is_a_one_line_error():
    from comat._face import lazy_face

    with pytest.raises(ValueError, match=r"^homes: expected each name of pkg's face once, got \['g'\] more than once$"):
        lazy_face("pkg", {"pkg.a": "f g", "pkg.b": "g"})
