# nrmlc: one-command set-up. Every target installs what it needs into .venv first.
#   make figures                 all figures and tables (synthetic sequences) -> out/figures (git-ignored)
#   make figures DATA=path       ... on real sequences (OTB or sparse-tracker layout)
#       options: OUT=figures (the committed real-data results), SEQUENCES=Car4,Caviar1,
#       SEEDS=5 SWEEP_SEEDS=2 ABLATION_SEEDS=1 JOBS=2 MAX_FRAMES=N ONLY=script,script
#       PEERS=dir (default <DATA>/../peer_results) DRY_RUN=1 (print the grid and the time it will
#       take, from a few seconds' measurement of this machine's speed, and stop)
#       DASK=tcp://host:8786 (run the grid on a Dask cluster; pip install -e .[cluster])
#       PORTABLE=1 (what figures/ was made with: the AVX2 level that any x86-64 CPU with AVX2 and FMA runs,
#       Intel or AMD: numba's haswell target, OpenBLAS's Haswell kernels, numpy's loops without AVX-512,
#       OpenCV's IPP at its AVX2 path (the live peers' boxes);
#       a numba cache and a run cache of its own; docs/RELIABILITY.md#determinism)
#       NUMBA_TARGET=cpu (compile the kernels for that CPU only, with caches of its own)
#   make test                    the linter (ruff) and the test suite (what CI runs)
#   make mutate                  mutation testing (mutmut) of the core, in a copy (.cache/mutate), with each
#                                module's fast tests; prints the score per module (not in CI: over an hour
#                                here; docs/research/mutation.md). MUTATE_JOBS=2, MUTANTS='glob glob'
#   make theorem                 numeric checks of Theorem 1 (seconds)
#   make bench [DATA=path]       kernel and tracker timings -> out/figures/bench.md (OUT=figures: committed)
#   make more-sequences MIRRORS=dir [DEST=../devdata]
#                                lay out the 24 more development targets, the OTB benchmark's results and
#                                attributes from local copies of public repositories (../shared/tools/lay_sequences.py)

PYTHON_BOOT ?= python3
VENV        ?= .venv
PY          := $(VENV)/bin/python
DATA        ?=
SEEDS       ?=
SWEEP_SEEDS ?=
ABLATION_SEEDS ?=
JOBS        ?=
OUT         ?=
SEQUENCES   ?=
PEERS       ?=
MAX_FRAMES  ?=
ONLY        ?=
DRY_RUN     ?=
STAMP       := $(VENV)/.installed
TEST_STAMP  := $(VENV)/.installed-test
DASK        ?=
NUMBA_TARGET ?=
PORTABLE    ?=
# The libraries that pick their code by the CPU at run time, held at the AVX2 level too (naming a
# level the CPU lacks is not an error for any of them).
ifneq ($(PORTABLE),)
NUMBA_TARGET := haswell
LIBRARY_ENV := OPENBLAS_CORETYPE=Haswell NPY_DISABLE_CPU_FEATURES="X86_V4 AVX512_ICL AVX512_SPR" OPENCV_IPP=avx2
TARGET_NAME := portable
else
LIBRARY_ENV :=
TARGET_NAME := $(NUMBA_TARGET)
endif
# numba's CPU name and its own default features (NUMBA_CPU_FEATURES empty), not the host's
TARGET_ENV  := $(if $(NUMBA_TARGET),$(LIBRARY_ENV) NUMBA_CPU_NAME=$(NUMBA_TARGET) NUMBA_CPU_FEATURES= NUMBA_CACHE_DIR=.cache/numba-$(TARGET_NAME))

export PYTHONHASHSEED := 0

MIRRORS     ?=
DEST        ?= ../devdata
LAY_SEQUENCES := ../shared/tools/lay_sequences.py

.PHONY: all install test mutate figures theorem bench more-sequences clean-runs clean

all: figures

$(STAMP): requirements.txt pyproject.toml
	$(PYTHON_BOOT) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -r requirements.txt
	# a static .pth entry (pyproject.toml's package-dir), so `import nrmlc` finds the package even from a
	# folder holding a clone named nrmlc
	$(PY) -m pip install --quiet --no-deps -e .
	touch $(STAMP)

install: $(STAMP)

# The tests also need the linter and the cluster extra (tests/test_cluster.py starts a Dask LocalCluster).
$(TEST_STAMP): $(STAMP)
	$(PY) -m pip install --quiet -e ".[test,lint,cluster]"
	touch $(TEST_STAMP)

test: $(TEST_STAMP)
	$(PY) -m ruff check .
	$(PY) -m pytest

# Mutation testing (docs/research/mutation.md): mutmut (the test extra) in a copy of the sources, so the working
# tree is never touched; the modules and their test subset are [tool.mutmut] in pyproject.toml, MUTANTS picks
# the functions (mutmut's globs; in algorithm.py only the template update and the occlusion judgement).
MUTATE_DIR  ?= .cache/mutate
MUTATE_JOBS ?= 2
MUTANTS     ?= nrmlc.workbench.metrics.* nrmlc.workbench.otb_results.* nrmlc.tracker.templates.* \
               nrmlc.tracker.algorithm.*update_templates* nrmlc.tracker.algorithm.*_result* nrmlc.kernels.*
MUTMUT      := $(abspath $(VENV))/bin/mutmut

# NUMBA_THREADING_LAYER=workqueue: numba's GNU OpenMP layer raise(SIGTERM)s in a child forked after its parent
# used it, and mutmut forks each mutant's worker after running the tests once (stats): without it every mutant
# whose tests run a parallel kernel died at once and was counted 'suspicious'.
mutate: $(TEST_STAMP)
	rm -rf $(MUTATE_DIR) && mkdir -p $(MUTATE_DIR)
	tar -cf - --exclude=__pycache__ nrmlc tests docs experiments README.md pyproject.toml | tar -xf - -C $(MUTATE_DIR)
	cd $(MUTATE_DIR) && NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 NUMBA_THREADING_LAYER=workqueue \
	    nice -n 10 \
	    $(MUTMUT) run --max-children $(MUTATE_JOBS) $(foreach m,$(MUTANTS),'$(m)') > mutmut.log 2>&1 \
	    || { tail -c 3000 mutmut.log; exit 1; }
	@cd $(MUTATE_DIR) && $(MUTMUT) results --all true > results.txt && \
	  grep -v ': not checked$$' results.txt | grep -v ': killed$$' > survivors.txt; \
	  awk -F': ' '{ n = $$1; sub(/^ +/, "", n); n = substr(n, 1, index(n, ".x") - 1); s = $$2; \
	    if (s == "not checked") next; if (!(n in all)) order[++k] = n; all[n]++; c[n, s]++ } \
	    END { printf "%-28s %8s %7s %8s %8s %8s %10s %6s\n", "module", "mutants", "killed", "timeout", \
	      "survived", "no tests", "suspicious", "score"; \
	      for (i = 1; i <= k; i++) { n = order[i]; d = c[n, "killed"] + c[n, "timeout"]; \
	        printf "%-28s %8d %7d %8d %8d %8d %10d %5.1f%%\n", n, all[n], c[n, "killed"], c[n, "timeout"], \
	          c[n, "survived"], c[n, "no tests"], c[n, "suspicious"], 100 * d / all[n] } }' results.txt; \
	  echo "(score: killed + timeout over all mutants run; the others: $(MUTATE_DIR)/survivors.txt," \
	       "'cd $(MUTATE_DIR) && $(MUTMUT) show NAME')"

figures: $(STAMP)
	$(TARGET_ENV) $(PY) -m experiments.run_all $(if $(NUMBA_TARGET),--cache .cache/runs-$(TARGET_NAME)) $(if $(DATA),--data "$(DATA)") $(if $(OUT),--out "$(OUT)") \
	    $(if $(SEQUENCES),--sequences "$(SEQUENCES)") $(if $(PEERS),--peers "$(PEERS)") \
	    $(if $(SEEDS),--seeds $(SEEDS)) $(if $(SWEEP_SEEDS),--sweep-seeds $(SWEEP_SEEDS)) \
	    $(if $(ABLATION_SEEDS),--ablation-seeds $(ABLATION_SEEDS)) $(if $(JOBS),--jobs $(JOBS)) \
	    $(if $(MAX_FRAMES),--max-frames $(MAX_FRAMES)) $(if $(ONLY),--only "$(ONLY)") $(if $(DRY_RUN),--dry-run) $(if $(DASK),--dask "$(DASK)")

theorem: $(STAMP)
	$(PY) -m experiments.paper.theorem1_checks

bench: $(STAMP)
	$(PY) -m experiments.bench $(if $(DATA),--data "$(DATA)") $(if $(OUT),--out "$(OUT)")

more-sequences:
	@test -f $(LAY_SEQUENCES) || { echo "error: $(LAY_SEQUENCES) not found (it is part of this workplace's shared/ folder)"; exit 2; }
	@test -n "$(MIRRORS)" || { echo "error: give MIRRORS=dir, the folder of the local copies that 'python3 $(LAY_SEQUENCES) --list x y' names"; exit 2; }
	python3 $(LAY_SEQUENCES) "$(MIRRORS)" "$(DEST)"

clean-runs:
	rm -rf .cache/runs

clean:
	rm -rf $(VENV) .cache
