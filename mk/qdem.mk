# QDEM verification scenes of seed 004 §3 (scenes/cantilever_*.toml, creep_recovery.toml,
# damped_vibration.toml) and the meshes they use: the cantilever of geo/cantilever.geo at
# several edge lengths h (meshes/cantilever_h<h>.msh).
# Included by the main Makefile, which defines GMSH, GMSH_FLAGS, RELEASE and VENV_STAMP.

CANTILEVER_H := 0.11 0.05 0.03 0.02 0.0105
QDEM_SCENES := cantilever_static cantilever_vibration creep_recovery damped_vibration
QDEM_QUICK_MESHES := meshes/cantilever_h0.03.msh meshes/cantilever_h0.05.msh meshes/cantilever_h0.11.msh
QDEM_QUICK := $(QDEM_SCENES:%=results/%-quick/summary.json)

.PHONY: qdem-quick paper bench-qdem

meshes/cantilever_h%.msh: geo/cantilever.geo | $(VENV_STAMP)
	$(GMSH_H)

## The quick presets (seconds each): part of the default `make`.
qdem-quick: $(QDEM_QUICK)
results/%-quick/summary.json: scenes/%.toml $(QDEM_QUICK_MESHES) $(RUST_SOURCES) | $(RELEASE)/ballast-qdem
	$(RELEASE)/ballast-qdem $< --preset quick --out $(@D)

## The paper's resolution and the convergence table over h (long: not part of tests).
QDEM_LEVELS := h005 base h002 paper
QDEM_PAPER_RUNS := $(foreach s,cantilever_static cantilever_vibration,$(foreach l,$(QDEM_LEVELS),results/paper/$(s)-$(l)/summary.json)) \
  results/paper/damped_vibration-paper/summary.json results/paper/creep_recovery-base/summary.json
paper: $(QDEM_PAPER_RUNS) | $(VENV_STAMP)
	$(PY) tools/qdem_report.py paper results/paper | tee results/paper/qdem_table.md
# A run is redone when the meshes change; a rebuilt solver or an edited scene does not
# redo hours of runs (delete results/paper/<run> to redo one).
results/paper/%/summary.json: $(foreach h,$(CANTILEVER_H),meshes/cantilever_h$(h).msh) | $(RELEASE)/ballast-qdem
	scene=$$(echo $* | sed 's/-[^-]*$$//'); level=$$(echo $* | sed 's/.*-//'); \
	if [ $$level = base ]; then preset=; else preset="--preset $$level"; fi; \
	$(RELEASE)/ballast-qdem scenes/$$scene.toml $$preset --out $(@D)

## Throughput at paper resolution (0.4 ms, 457 steps) on 1 and 2 threads, with peak
## memory: the vector kernel and the portable one (the baseline, BALLAST_KERNEL=portable),
## QDEM_BENCH_REPEAT runs each, alternating (the machine is shared: the table keeps
## medians).
QDEM_BENCH_REPEAT ?= 3
QDEM_BENCH_OUT := results/bench
bench: bench-qdem
bench-qdem: $(RELEASE)/ballast-qdem meshes/cantilever_h0.0105.msh | $(VENV_STAMP)
	@rm -rf $(QDEM_BENCH_OUT)/qdem
	@for k in $$(seq $(QDEM_BENCH_REPEAT)); do \
	  for kernel in auto portable; do \
	    for t in 1 2; do \
	      d=$(QDEM_BENCH_OUT)/qdem/$$kernel-threads-$$t/run-$$k; mkdir -p $$d; \
	      BALLAST_KERNEL=$$kernel /usr/bin/time -f %M -o $$d/max_rss_kb \
	        $(RELEASE)/ballast-qdem scenes/cantilever_static.toml --preset bench --threads $$t \
	        --out $$d >/dev/null || exit 1; \
	    done; \
	  done; \
	done
	$(PY) tools/qdem_report.py bench $(QDEM_BENCH_OUT)/qdem | tee $(QDEM_BENCH_OUT)/qdem_bench.md

## Chart of the quick runs (vibration, creep–recovery, damped vibration).
QDEM_CHART := results/qdem_quick.png
$(QDEM_CHART): tools/qdem_report.py $(QDEM_QUICK) | $(VENV_STAMP)
	$(PY) $< charts $@
