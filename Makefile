# One-command set-up: every target creates .venv and installs the project on first use.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
# BenchMARL pins TorchRL < 0.12, the interop extra 0.14.1: the outside reference has a venv of its own.
BM_VENV  := .venv-benchmarl
BM_STAMP := $(BM_VENV)/.installed

.PHONY: setup demo test test-slow test-learning test-benchmarl test-all test-cluster test-wheel test-server bench mjcf clean docs lint

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --disable-pip-version-check -q -e ".[test,robotarium,ray,interop]"
	touch $(STAMP)

$(BM_STAMP): pyproject.toml
	$(PYTHON) -m venv $(BM_VENV)
	$(BM_VENV)/bin/pip install --disable-pip-version-check -q -e ".[test,benchmarl]"
	touch $(BM_STAMP)

setup: $(STAMP)

demo: $(STAMP)  ## safety filter, the tasks, then the shipped COMAT policy: .rrd, video, checked export in runs/demo (4 min 24 s on a fresh 2-core machine, install included; about 2 min once installed)
	$(BIN)/comat demo

test: $(STAMP)  ## the fast suite on every core (about 7 minutes on 2 cores: 1,679 passed and 20 skipped in 6 min 58 s by `time make test`, 2026-12-08 at b32f6b2, nothing else running; 8 min 7 s the day before, 9 min 30 s before tests stopped leaking torch threads)
	$(BIN)/python -m pytest -q -n auto --dist loadfile

test-slow: $(STAMP)  ## long tests: 200 randomized episodes per safety scenario and tier, fidelity spread
	$(BIN)/python -m pytest -q -m slow

test-learning: $(STAMP)  ## learning checks: each new learner trains ten PPO updates on PCP (about 1 minute)
	$(BIN)/python -m pytest -q -m learning

test-benchmarl: $(BM_STAMP)  ## BenchMARL's own MAPPO trains on a fixed comat team, in .venv-benchmarl (about 1 minute, install aside)
	$(BM_VENV)/bin/python -m pytest -q -m benchmarl tests/test_benchmarl.py

test-all: test test-slow test-cluster test-learning test-benchmarl

docs: $(STAMP)  ## the documentation site into build/site (MkDocs, strict: warnings and broken links fail)
	$(BIN)/pip install --disable-pip-version-check -q -e ".[docs]"
	$(BIN)/mkdocs build --strict

lint: $(STAMP)  ## ruff (lint + format check), the import-layering contracts of pyproject.toml (import-linter) and the budgets of tools/budgets.toml
	$(BIN)/pip install --disable-pip-version-check -q -e ".[lint]"
	$(BIN)/ruff check comat sim2real tests benchmarks results tools
	$(BIN)/ruff format --check comat sim2real tests benchmarks results tools
	$(BIN)/lint-imports
	$(BIN)/python tools/budgets.py

test-cluster: $(STAMP)  ## Ray clusters: kill -9 of a sweep, two nodes on loopback, ray job submit (about 7 minutes)
	$(BIN)/python -m pytest -q -m cluster

test-wheel:  ## the built wheel in a fresh venv: train, eval, export, rollout from an empty folder (about 4 minutes)
	bash .ci/wheel-smoke

test-server: $(STAMP)  ## every task's exports run to the end under the Robotarium server's Pythons, 3.8 (numpy 1.23.5) and 3.10 (numpy 2.2.6), in .venv-py38 / .venv-py310 built from pyenv (about 3 minutes on 2 cores: 40 runs in 161 s, 2026-12-07; building the two venvs first adds about 2.5 minutes)
	$(BIN)/python -m sim2real.server_pythons

bench: $(STAMP)  ## comat bench sim, env, learn and fidelity; JSON under benchmarks/results/
	$(BIN)/comat bench sim
	$(BIN)/comat bench env
	$(BIN)/comat bench learn
	$(BIN)/comat bench fidelity

mjcf: $(STAMP)  ## regenerate the golden MJCF files
	$(BIN)/comat mjcf --out assets/mjcf

clean:
	rm -rf $(VENV) $(BM_VENV) .venv-py38 .venv-py310 .pytest_cache
