# Speed/accuracy of the cantilever (seed 004 §3.1): ballast-qdem over mesh size × time-step
# factor and ballast-fem over mesh size, charted by `ballast-post speed-accuracy` (error in
# tip deflection and first frequency against wall time and mesh size; SVG, PNG, table).
# Runs of `make paper` (results/paper) are added to the chart when they exist.
# Included by the main Makefile, which defines RELEASE.

SA_OUT := results/speed_accuracy
SA_FEM_H := 0.11 0.05 0.03 0.02 0.0105
SA_QDEM_H := 0.11 0.05
SA_DT := 0.5 0.8 0.95

.PHONY: speed-accuracy
speed-accuracy: $(RELEASE)/ballast-qdem $(RELEASE)/ballast-fem $(RELEASE)/ballast-post \
		$(foreach h,$(SA_FEM_H),meshes/cantilever_h$(h).msh)
	@set -e; mkdir -p $(SA_OUT); \
	for h in $(SA_FEM_H); do \
	  mesh=../meshes/cantilever_h$$h.msh; \
	  $(RELEASE)/ballast-fem static scenes/cantilever_static.toml --set mesh.file=$$mesh \
	    --out $(SA_OUT)/fem-static-h$$h >/dev/null; \
	  $(RELEASE)/ballast-fem modes scenes/cantilever_vibration.toml --set mesh.file=$$mesh \
	    --out $(SA_OUT)/fem-modes-h$$h >/dev/null; \
	done; \
	for h in $(SA_QDEM_H); do for f in $(SA_DT); do \
	  mesh=../meshes/cantilever_h$$h.msh; \
	  $(RELEASE)/ballast-qdem scenes/cantilever_static.toml --set mesh.file=$$mesh \
	    --set qdem.dt_factor=$$f --set qdem.frames=1 --out $(SA_OUT)/qdem-static-h$$h-dt$$f >/dev/null; \
	  $(RELEASE)/ballast-qdem scenes/cantilever_vibration.toml --set mesh.file=$$mesh \
	    --set qdem.dt_factor=$$f --set qdem.frames=1 --out $(SA_OUT)/qdem-vibration-h$$h-dt$$f >/dev/null; \
	done; done
	$(RELEASE)/ballast-post speed-accuracy $(SA_OUT) $(wildcard results/paper) --out $(SA_OUT)/chart
