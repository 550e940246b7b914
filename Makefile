# Two entry points: `make run` and `make test`. Both create .venv on first use.
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python

.PHONY: run test test-rl lint format bench docs clean gl-libs

# Headless rendering needs Mesa's EGL (or OSMesa). When neither library is installed they
# are installed with apt-get where that is possible (as root), else the command is shown.
gl-libs:
	@if ! ldconfig -p 2>/dev/null | grep -q -E 'libEGL\.so\.1|libOSMesa\.so'; then \
	  if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null; then \
	    echo "installing Mesa's EGL for headless rendering"; \
	    apt-get update -qq && apt-get install -y -qq libegl1 libgl1-mesa-dri >/dev/null; \
	  else \
	    echo "warning: rendering needs Mesa's EGL: sudo apt-get install libegl1 libgl1-mesa-dri"; \
	  fi; \
	fi

$(VENV)/.stamp-run: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e ".[real,maps]"
	touch $@

$(VENV)/.stamp-dev: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e ".[dev,cluster,real,maps]"
	touch $(VENV)/.stamp-run $@

run: $(VENV)/.stamp-run gl-libs
	$(VENV)/bin/twin run scenarios/paper_hall.toml --fidelity render --strategy paper --out out/paper_hall --overwrite

# Two workers; a worker left without tests takes half of the other's queue (worksteal), so
# that neither stands idle at the end while the other works through its last long tests.
test: $(VENV)/.stamp-dev gl-libs
	$(VENV)/bin/ruff check .
	$(VENV)/bin/ruff format --check .
	$(PY) -m pytest -n 2 --dist worksteal -q

# The reinforcement-learning integration tests (tests/rl: MaskablePPO through the environment
# and through twin.envs.sb3) in a venv of their own, .venv-rl, with the rl extra (sb3-contrib,
# Stable-Baselines3, torch: PyPI serves torch's CUDA build, several GB). make test leaves
# tests/rl out (tests/conftest.py) and its venv has no torch.
VENV_RL ?= .venv-rl
PY_RL   := $(VENV_RL)/bin/python

$(VENV_RL)/.stamp-rl: pyproject.toml
	$(PYTHON) -m venv $(VENV_RL)
	$(PY_RL) -m pip install --quiet --upgrade pip
	$(PY_RL) -m pip install --quiet -e ".[dev,rl]"
	touch $@

test-rl: $(VENV_RL)/.stamp-rl
	$(PY_RL) -m pytest -q tests/rl

lint: $(VENV)/.stamp-dev
	$(VENV)/bin/ruff check .
	$(VENV)/bin/ruff format --check .

format: $(VENV)/.stamp-dev
	$(VENV)/bin/ruff format .
	$(VENV)/bin/ruff check --fix .

# The documentation site (docs/, mkdocs.yml) into out/site/; a warning (a broken link, a
# missing page or image) fails the build.
docs: $(VENV)/.stamp-dev
	$(VENV)/bin/mkdocs build --strict

bench: $(VENV)/.stamp-dev
	@for b in benchmarks/bench_*.py; do echo "== $$b"; $(PY) $$b || exit 1; done

clean:
	rm -rf $(VENV) $(VENV_RL) out .pytest_cache .ruff_cache
