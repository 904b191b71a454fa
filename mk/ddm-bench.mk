# DDM parallel efficiency (issue #7, seed 000 Tables 1–2): ballast-pack's quick bed
# (synchronous DDM, one subdomain per sleeper) on 1 and 2 threads, DDM_BENCH_REPEAT runs
# each, alternating; the packings must be identical. tools/ddm_bench.py prints the phase
# times in the layout of the seed's Table 1 and the speedup and efficiency of the
# parallel part and of the whole run as in its Table 2. Part of `make bench`.
# Included by the main Makefile, which defines PY, RELEASE, STONE_MESHES, VENV_STAMP.

DDM_BENCH_REPEAT ?= 1
DDM_BENCH_THREADS ?= 1 2
DDM_BENCH_OUT := results/bench-ddm

.PHONY: bench-ddm
bench: bench-ddm

bench-ddm: $(RELEASE)/ballast-pack $(STONE_MESHES) | $(VENV_STAMP)
	@rm -rf $(DDM_BENCH_OUT)
	@for k in $$(seq $(DDM_BENCH_REPEAT)); do \
	  for t in $(DDM_BENCH_THREADS); do \
	    $(RELEASE)/ballast-pack scenes/bed.toml --preset quick --threads $$t \
	      --out $(DDM_BENCH_OUT)/threads-$$t/run-$$k >/dev/null 2>&1 || exit 1; \
	  done; \
	done
	$(PY) tools/ddm_bench.py $(DDM_BENCH_OUT) | tee $(DDM_BENCH_OUT)/table.md
