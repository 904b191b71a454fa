# NSCD throughput (issue #5): the NLGS's contact updates/s on scenes/drop_box.toml, with
# the phase times (detect, build, solve, update), NSCD_BENCH_REPEAT runs of each case
# (alternating; the machine is shared, so the table keeps medians). Part of `make bench`.
#   - preset bench (200 stones): sequential NLGS on 1 thread, AVX2+FMA and portable
#     kernels (the baseline, BALLAST_KERNEL=portable);
#   - preset bench_ddm (800 stones): sequential NLGS on 1 thread, and the synchronous
#     DDM on 2 threads (the per-core figure of the parallel NLGS).
# Included by the main Makefile, which defines PY, RELEASE, STONE_MESHES, VENV_STAMP.

NSCD_BENCH_REPEAT ?= 3
NSCD_BENCH_OUT := results/bench-nscd
# name : preset : threads : kernel : extra arguments
NSCD_BENCH_CASES := \
  small-seq-1:bench:1:auto: \
  small-seq-1-portable:bench:1:portable: \
  large-seq-1:bench_ddm:1:auto: \
  large-ddm-2:bench_ddm:2:auto:--set=ddm.driver=synchronous

.PHONY: bench-nscd
bench: bench-nscd

bench-nscd: $(RELEASE)/ballast-nscd $(STONE_MESHES) | $(VENV_STAMP)
	@rm -rf $(NSCD_BENCH_OUT)
	@for k in $$(seq $(NSCD_BENCH_REPEAT)); do \
	  for case in $(NSCD_BENCH_CASES); do \
	    IFS=: read -r name preset threads kernel extra <<< "$$case"; \
	    BALLAST_KERNEL=$$kernel $(RELEASE)/ballast-nscd scenes/drop_box.toml --preset $$preset \
	      --threads $$threads $${extra/=/ } --out $(NSCD_BENCH_OUT)/$$name/run-$$k >/dev/null || exit 1; \
	  done; \
	done
	$(PY) tools/nscd_bench.py $(NSCD_BENCH_OUT) | tee $(NSCD_BENCH_OUT)/table.md

# The NLGS sweep alone on a synthetic problem of 118 000 contacts between 7 000 bodies
# (examples/nlgs_sweep.rs; docs/ddm.md, "Drivers"): ns per contact and sweep with none,
# 5 % and 20 % of the contacts pressed shut (µ = 1; the 20 % case also with µ = 100,
# mostly sticking), on one thread, then the 20 % case twice at
# once (one per core: do two sweeps share the memory bandwidth?). Seconds long; part of
# `make bench`.
SWEEP_BENCH_CASES := 0:1 0.05:1 0.2:1 0.2:100
.PHONY: bench-sweep
bench: bench-sweep
bench-sweep:
	$(CARGO) build --release --locked --example nlgs_sweep
	@for case in $(SWEEP_BENCH_CASES); do \
	  RAYON_NUM_THREADS=1 $(RELEASE)/examples/nlgs_sweep 7000 300 $${case%:*} $${case#*:} || exit 1; \
	done
	@echo "two at once:"; \
	RAYON_NUM_THREADS=1 $(RELEASE)/examples/nlgs_sweep 7000 300 0.2 1 & \
	RAYON_NUM_THREADS=1 $(RELEASE)/examples/nlgs_sweep 7000 300 0.2 1; wait
