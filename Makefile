# Two commands for a fresh machine: `make demo` and `make test` (see README).
# Both create .venv on first use and are idempotent: the install step re-runs only when
# pyproject.toml changes.

PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
# Torch is pinned to a CPU build before anything else: left to stable-baselines3, pip would
# pick a CUDA build of several GB. On Linux machines without a local CPU wheel, set
# TORCH_PIP_ARGS="--index-url <the PyTorch CPU wheel index>" (see README).
TORCH_SPEC ?= torch==2.13.0
TORCH_PIP_ARGS ?=
DEMO_OUT ?= demo_out

.PHONY: demo test check docs install install-rllib lint bench clean

$(VENV)/.stamp-base:
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet "$(TORCH_SPEC)" $(TORCH_PIP_ARGS)
	@touch $@

$(VENV)/.stamp-install: $(VENV)/.stamp-base pyproject.toml
	$(PY) -m pip install --quiet -e ".[dev,ray,data]"
	@touch $@

install: $(VENV)/.stamp-install

# RLlib in a venv of its own: ray[rllib] pins gymnasium 1.2.2, the suite runs on 1.4.
# tests/test_rllib.py runs PPO in it.
RLLIB_VENV ?= .venv-rllib
$(RLLIB_VENV)/.stamp-install: pyproject.toml
	$(PYTHON) -m venv $(RLLIB_VENV)
	$(RLLIB_VENV)/bin/python -m pip install --quiet "$(TORCH_SPEC)" $(TORCH_PIP_ARGS)
	$(RLLIB_VENV)/bin/python -m pip install --quiet -e ".[rllib]"
	@touch $@

install-rllib: $(RLLIB_VENV)/.stamp-install

demo: install
	$(PY) -m pour_gym.apps.cli demo --out $(DEMO_OUT)

# Tests run in $(TEST_WORKERS) processes (pytest-xdist), a test file per process at a time (its
# module fixtures built once); the fluid kernel is compiled once for all of them.
TEST_WORKERS ?= 2
PYTEST := $(PY) -m pytest -q -n $(TEST_WORKERS) --dist loadfile

# Everything, as CI runs it (after `make lint`): slow tests, RLlib, the docs site.
test: install install-rllib
	$(PYTEST)

lint: install
	$(VENV)/bin/ruff check .
	$(VENV)/bin/ruff format --check .

# The edit-test loop: ruff, then the tests not marked slow.
check: lint
	$(PYTEST) -m "not slow" --deselect tests/test_rllib.py

# The documentation site (docs/, mkdocs.yml) into site/; a broken link or page fails.
docs: install
	$(VENV)/bin/mkdocs build --strict

bench: install
	$(PY) -m pour_gym.apps.cli bench reconstruct

clean:
	rm -rf $(VENV) $(RLLIB_VENV) $(DEMO_OUT) build site *.egg-info
