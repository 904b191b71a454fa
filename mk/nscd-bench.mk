# NSCD throughput (issue #5): the NLGS's contact updates/s on scenes/drop_box.toml's
# bench preset (200 stones, 0.45 s), on 1 and 2 threads, NSCD_BENCH_REPEAT runs each
# (alternating thread counts; the machine is shared, so the table keeps medians), with the
# phase times (detect, build, solve, update). Part of `make bench`.
# Included by the main Makefile, which defines PY, RELEASE, STONE_MESHES, VENV_STAMP.

NSCD_BENCH_REPEAT ?= 3
NSCD_BENCH_THREADS ?= 1 2
NSCD_BENCH_OUT := results/bench-nscd

.PHONY: bench-nscd
bench: bench-nscd

bench-nscd: $(RELEASE)/ballast-nscd $(STONE_MESHES) | $(VENV_STAMP)
	@rm -rf $(NSCD_BENCH_OUT)
	@for k in $$(seq $(NSCD_BENCH_REPEAT)); do \
	  for t in $(NSCD_BENCH_THREADS); do \
	    $(RELEASE)/ballast-nscd scenes/drop_box.toml --preset bench --threads $$t \
	      --out $(NSCD_BENCH_OUT)/threads-$$t/run-$$k >/dev/null || exit 1; \
	  done; \
	done
	$(PY) tools/nscd_bench.py $(NSCD_BENCH_OUT) | tee $(NSCD_BENCH_OUT)/table.md
