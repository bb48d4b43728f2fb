# crosshead: two commands do everything on a fresh Debian 12 machine, set-up included.
#   make run    hook No. 05, default mesh, all outputs in results/05/
#   make test   the test suite (coarse meshes; a few minutes)
# Longer studies: make converge, make bench, make sizes (one target per size: make 05, make 1.6, ...)
SHELL := /bin/bash
PY := .venv/bin/python
SETUP := .venv/.setup-done
# make run / make converge use every core: the error bar's meshes are made one per rank at
# once, the requested mesh is solved by all ranks, the coarser ones side by side
# (No. 05: 12.9 s on 2 ranks, median of 5; 16.0 s on 1, one run). RANKS=1 runs without MPI.
RANKS ?= $(shell nproc 2>/dev/null || echo 1)
RUN := $(if $(filter 1,$(RANKS)),$(PY) -m pipeline,$(PY) -m pipeline.launch $(RANKS))
SIZES := $(shell awk -F, '!/^\#/ && $$1 != "size" && NF > 1 {print $$1}' geometry/sizes.csv)

.PHONY: run test converge bench sizes setup clean $(SIZES)

run: $(SETUP)
	$(RUN) run --size 05 --out results/05

test: $(SETUP)
	$(PY) -m pytest -q tests

converge: $(SETUP)
	$(RUN) converge --size 05 --out results/05-converge

# Run time against error (P1/P2/P3 x mesh levels x pmg/gamg/hypre/mumps, CalculiX iterative and
# spooles; on 2 cores: every solver on the finest P2 mesh, P2 pmg and CalculiX on every level),
# on the pipeline's pilot-refined meshes; makes the convergence study first if
# results/05-converge/results.json is missing. Errors are measured against the independent
# P3 + MUMPS solution of tests/test_regression.py (global 113.79, critical 66.27 MPa);
# the study's own extrapolation of the global peak carries ± 5.64 MPa (order 0.76; make converge, c763ad0).
# 55 min on 2 cores (2026-11-22); add --pilot both for the plain graded meshes too (~1.5 h).
BENCH_ARGS ?= --pilot on --factors 4.0,2.5,2.0,1.3,1.0 --p3-factors 3.0,2.5,2.0 --repeats 3 \
	--ccx-solvers iterative,spooles --ranks-at targets --reference-values 113.79,66.27
bench: $(SETUP)
	$(PY) -m bench --out results/bench --ranks 1,2 $(BENCH_ARGS)

setup: $(SETUP)

$(SETUP): tools/setup.sh requirements.txt constraints.txt
	bash tools/setup.sh

$(SIZES): $(SETUP)
	$(PY) -m pipeline run --size $@ --out results/$@

# Every size (make -j2 sizes runs two at a time), then the batch summary in results/summary/.
sizes: $(SIZES)
	$(PY) -m pipeline.summary results --out results/summary

clean:
	rm -rf results
