# FC3D comparison: ballast-nscd's NSGS against Siconos 4.4 NSGS (Debian python3-siconos)
# on every problem of ../shared/fc3d, at two tolerances with a cap of 10 000 sweeps, both
# from r = 0, solver time only. Each run is a fresh process on both sides (so both pay the
# same cold start), alternating ours and Siconos's, FC3D_REPEAT times per file and
# tolerance; the table keeps the fastest of each. See docs/fc3d.md.
# Included by the main Makefile, which defines RELEASE.

FC3D_DIR ?= ../shared/fc3d
FC3D_TOLERANCES ?= 1e-6 1e-8
FC3D_MAX_ITER ?= 10000
FC3D_REPEAT ?= 3
FC3D_OUT := results/compare_fc3d
SICONOS_PYTHON := /usr/bin/python3
SICONOS_PEER := tools/peers/siconos

.PHONY: compare-fc3d siconos-peer

siconos-peer:
	@sh $(SICONOS_PEER)/install.sh

compare-fc3d: $(RELEASE)/ballast-nscd siconos-peer
	@files="$$(ls $(FC3D_DIR)/*.dat $(FC3D_DIR)/*.hdf5 2>/dev/null)"; \
	test -n "$$files" || { echo "compare-fc3d: no .dat or .hdf5 in $(FC3D_DIR)" >&2; exit 1; }; \
	mkdir -p $(FC3D_OUT) && : > $(FC3D_OUT)/ours.jsonl && : > $(FC3D_OUT)/siconos.jsonl; \
	for file in $$files; do \
	  for tol in $(FC3D_TOLERANCES); do \
	    for run in $$(seq $(FC3D_REPEAT)); do \
	      $(RELEASE)/ballast-nscd fc3d "$$file" --tol $$tol --max-iter $(FC3D_MAX_ITER) --json \
	        >> $(FC3D_OUT)/ours.jsonl || exit 1; \
	      $(SICONOS_PYTHON) $(SICONOS_PEER)/fc3d_nsgs.py --tol $$tol --max-iter $(FC3D_MAX_ITER) \
	        "$$file" 2>/dev/null | grep '^{' >> $(FC3D_OUT)/siconos.jsonl \
	        || { echo "compare-fc3d: Siconos failed on $$file" >&2; exit 1; }; \
	    done; \
	  done; \
	done
	@$(SICONOS_PYTHON) $(SICONOS_PEER)/compare_table.py $(FC3D_OUT)/ours.jsonl $(FC3D_OUT)/siconos.jsonl \
	  | tee $(FC3D_OUT)/table.md
