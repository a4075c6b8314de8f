# nrmlc: one-command set-up. Every target installs what it needs into .venv first.
#   make figures                 all figures and tables (synthetic sequences)
#   make figures DATA=path       ... on real sequences (OTB or sparse-tracker layout)
#   make test                    the test suite (what CI runs)
#   make theorem                 numeric checks of Theorem 1 (seconds)
#   make bench                   kernel and tracker timings -> figures/bench.json

PYTHON_BOOT ?= python3
VENV        ?= .venv
PY          := $(VENV)/bin/python
DATA        ?=
SEEDS       ?=
SWEEP_SEEDS ?=
JOBS        ?=
STAMP       := $(VENV)/.installed

export PYTHONHASHSEED := 0

.PHONY: all install test figures theorem bench clean-runs clean

all: figures

$(STAMP): requirements.txt pyproject.toml
	$(PYTHON_BOOT) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -r requirements.txt
	$(PY) -m pip install --quiet --no-deps -e .
	touch $(STAMP)

install: $(STAMP)

test: $(STAMP)
	$(PY) -m pytest

figures: $(STAMP)
	$(PY) -m experiments.run_all $(if $(DATA),--data "$(DATA)") $(if $(SEEDS),--seeds $(SEEDS)) $(if $(SWEEP_SEEDS),--sweep-seeds $(SWEEP_SEEDS)) $(if $(JOBS),--jobs $(JOBS))

theorem: $(STAMP)
	$(PY) -m experiments.theorem1_checks

bench: $(STAMP)
	$(PY) -m experiments.bench $(if $(DATA),--data "$(DATA)")

clean-runs:
	rm -rf .cache/runs

clean:
	rm -rf $(VENV) .cache
