# crosshead: two commands do everything on a fresh Debian 12 machine, set-up included.
#   make run    hook No. 05, default mesh, all outputs in results/05/
#   make test   the linter and the test suite (coarse meshes; about 20 minutes); make test-fast: about a minute
# Longer studies: make converge, make bench, make sizes (one target per size: make 05, make 1.6, ...)
SHELL := /bin/bash
PY := .venv/bin/python
SETUP := .venv/.setup-done
# run, converge, sizes and each size use every core (MPI ranks through pipeline.runtime.launch);
# RANKS=1 runs without MPI.
RANKS ?= $(shell nproc 2>/dev/null || echo 1)
CROSSHEAD := .venv/bin/crosshead
RUN := $(if $(filter 1,$(RANKS)),$(CROSSHEAD),$(PY) -m pipeline.runtime.launch $(RANKS))
SIZES := $(shell awk -F, '!/^\#/ && $$1 != "size" && NF > 1 {print $$1}' geometry/sizes.csv)

.PHONY: run test test-fast lint mutate converge bench bench-peer bench-sweeps reference load-reference sizes setup clean clean-cache $(SIZES)

run: $(SETUP)
	$(RUN) run --size 05 --out results/05

# The whole suite (CI runs this, with the linter first); test-fast: the edit-test loop, the
# tests not marked slow (under a minute).
test: $(SETUP)
	$(PY) -m ruff check .
	$(PY) -m pytest -q tests

test-fast: $(SETUP)
	$(PY) -m pytest -q -m "not slow" tests

lint: $(SETUP)
	$(PY) -m ruff check .

# Targeted mutation testing of the modules that decide the numbers, against the fast tests,
# in a scratch copy of the tree (tools/mutate.py; score and survivors: docs/testing.md).
# About 6 minutes on 2 cores.
mutate: $(SETUP)
	$(PY) tools/mutate.py

converge: $(SETUP)
	$(RUN) converge --size 05 --out results/05-converge

# Run time against error: every order, solver and mesh level, and CalculiX, on the
# pipeline's pilot-refined meshes; errors against --reference-values (docs/accuracy.md).
# About an hour on 2 cores; figures and how to read them: docs/performance.md.
BENCH_ARGS ?= --pilot on --factors 4.0,2.5,2.0,1.3,1.0 --p3-factors 3.0,2.5,2.0 --repeats 3 \
	--ccx-solvers iterative,spooles --ranks-at targets --reference-values 113.82,66.27
# Then the critical peak alone on the meshes `run --want critical` uses (the bore edges
# refined where the dimensions put them, no pilot), CalculiX on the same meshes: the
# critical-peak target's own comparison (about a minute).
BENCH_CRITICAL_ARGS ?= --orders 2 --solvers pmg --factors 10,8,6,5,4 --pilot on --want critical \
	--repeats 3 --reference-values 113.82,66.27
# Then the fair peer: CalculiX as its users run it (a mesh graded at the raisers by size
# fields, no pilot, peaks from its .frd) beside the pipeline and CalculiX on the pipeline's
# meshes, interleaved (bench/peer.py; 8 min measured at load average 4-7 on 2 cores).
BENCH_PEER_ARGS ?= --repeats 3 --reference-values 113.82,66.27
# Last, the sensitivity section's cost: make run with it, without it (--no-sensitivity) and
# the make run of the round before it (version 0.6), interleaved, cache off, medians of 3;
# target: with the section <= 2x the earlier run (about 5 minutes on a quiet machine).
RUN_COST_ARGS ?= --repeats 3
bench: $(SETUP)
	$(PY) -m bench --out results/bench --ranks 1,2 $(BENCH_ARGS)
	$(PY) -m bench --out results/bench-critical $(BENCH_CRITICAL_ARGS)
	$(PY) -m bench.peer --out results/bench-peer $(BENCH_PEER_ARGS)
	$(PY) -m bench.run_cost --out results/bench-run --peer results/bench-peer/peer.json --sweeps results/bench-sweeps/sweeps.json $(RUN_COST_ARGS)

bench-peer: $(SETUP)
	$(PY) -m bench.peer --out results/bench-peer $(BENCH_PEER_ARGS)

# Design-study throughput: every size on 2 ranks and on 1, and a 24-variant rf x dj grid of
# No. 05 (targets 60 s, 90 s, 2 ranks >= 1.8x): about 10 minutes per repeat on 2 cores.
SWEEP_BENCH_ARGS ?= --repeats 1 $(if $(SWEEP_BENCH_BASE),--base $(SWEEP_BENCH_BASE))
bench-sweeps: $(SETUP)
	$(PY) -m bench.sweeps --out results/bench-sweeps $(SWEEP_BENCH_ARGS)

# The independent reference of No. 05's global (fillet) peak: P2, P3, P4 on meshes refined in
# a ball at the fillet's hot spot, peak sampled on the exact fillet surface (docs/fillet-reference.md).
# About 6 minutes on 2 cores; a re-run skips the points already in results/fillet-reference/.
reference: $(SETUP)
	$(PY) -m bench.fillet_reference --out results/fillet-reference --ranks $(RANKS)

# An independent check of the bearing load model: the journal in a side-plate bore with
# CalculiX's contact (zero clearance, H7/g6, H9/d9) beside the cos θ model on the same mesh
# (docs/load-reference.md), on a crosshead mesh whose journal is fine enough for the contact.
# About 11 minutes on 2 cores; a re-run skips the points already in results/load-reference/.
LOAD_REFERENCE_ARGS ?= --factors 2.0 --size-body-mm 1.0
load-reference: $(SETUP)
	$(PY) -m bench.load_reference --out results/load-reference $(LOAD_REFERENCE_ARGS)

setup: $(SETUP)

$(SETUP): tools/setup.sh requirements.txt constraints.txt pyproject.toml
	bash tools/setup.sh

# One size, on every core as make run (RANKS=1: without MPI).
$(SIZES): $(SETUP)
	$(RUN) run --size $@ --out results/$@

# Every size as one sweep over the MPI ranks (dynamic: a slow size holds one rank; a re-run
# skips finished sizes), then the batch summary in results/summary/.
sizes: $(SETUP)
	$(RUN) sweep --sizes all --out results/sizes $(SIZES_OPTIONS)
	$(PY) -m pipeline.study.summary results/sizes/variants --all --out results/summary

# Removes what crosshead wrote under results/: its results folders (those carrying its
# .crosshead-results marker, its own JSON), staging folders and the locks of runs that are
# not running; keeps and names anything else, a user's file inside a results folder too
# (pipeline/runtime/folders.py, clean). No MPI or numerics: runs before make setup too.
clean:
	@if [ -d results ]; then $(if $(wildcard $(PY)),$(PY),python3) -m pipeline.runtime.folders results; fi

# Meshes and pilot places kept for runs that change only load, E or the allowable.
clean-cache:
	rm -rf .venv/cache/runs
