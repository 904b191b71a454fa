# FEM comparison (issue #4): ballast-fem against CalculiX 2.20 (Debian calculix-ccx) on
# the cantilever of seed 004 §3.1 (scenes/cantilever_static.toml) at each level of
# COMPARE_FEM_LEVELS (presets of that scene; `base` = no preset): the same mesh, fixes
# and per-node loads; static tip deflection, the 4 lowest frequencies and wall times
# (`ballast-fem both`: static + modes in one process, against one ccx run with a *STATIC and a
# *FREQUENCY step). QDEM's figures on the same mesh are read from results/paper/
# (`make paper`), else results/ (`make qdem-quick`), when those runs exist, and printed
# as "not run" otherwise: compare-fem never runs QDEM.
# The table goes to results/compare_fem/table.md. Each level's runs are file targets
# (redone when ballast-fem, the peer or the mesh change); otherwise a second
# `make compare-fem` only reprints the table.
#
# Also: `make sleeper-modes` (scenes/sleeper_modes.toml, free–free and on a Winkler bed,
# three mesh sizes) and the sleeper meshes at other edge lengths.
# Included by the main Makefile, which defines PY, GMSH, GMSH_FLAGS, RELEASE, VENV_STAMP.

COMPARE_FEM_LEVELS ?= h005 base paper
COMPARE_FEM_OUT := results/compare_fem
CALCULIX_PEER := tools/peers/calculix
CALCULIX_STAMP := $(COMPARE_FEM_OUT)/.calculix-installed

.PHONY: compare-fem calculix-peer sleeper-modes

calculix-peer: $(CALCULIX_STAMP)
$(CALCULIX_STAMP): $(CALCULIX_PEER)/install.sh
	@sh $<
	@mkdir -p $(@D) && touch $@

compare-fem: $(foreach l,$(COMPARE_FEM_LEVELS),$(COMPARE_FEM_OUT)/$(l)/ballast.json $(COMPARE_FEM_OUT)/$(l)/calculix.json) | $(VENV_STAMP)
	@$(PY) $(CALCULIX_PEER)/compare_fem.py table $(COMPARE_FEM_LEVELS) --dir $(COMPARE_FEM_OUT) \
	  > $(COMPARE_FEM_OUT)/table.md.tmp && mv $(COMPARE_FEM_OUT)/table.md.tmp $(COMPARE_FEM_OUT)/table.md
	@cat $(COMPARE_FEM_OUT)/table.md

# The mesh a level uses (cantilever_static.toml: h005 → h0.05, base → h0.03, …).
compare_fem_mesh = meshes/cantilever_$(if $(filter base,$(1)),h0.03,$(if $(filter paper,$(1)),h0.0105,$(subst h00,h0.0,$(1)))).msh

# One level's two runs (an eval template: no secondary expansion for the whole Makefile).
define COMPARE_FEM_LEVEL
$(COMPARE_FEM_OUT)/$(1)/ballast.json: $(RELEASE)/ballast-fem scenes/cantilever_static.toml $(call compare_fem_mesh,$(1)) $(CALCULIX_PEER)/compare_fem.py | $(VENV_STAMP)
	@mkdir -p $$(@D)
	$(PY) $(CALCULIX_PEER)/compare_fem.py ballast $(1) $$@

$(COMPARE_FEM_OUT)/$(1)/calculix.json: scenes/cantilever_static.toml $(call compare_fem_mesh,$(1)) $(CALCULIX_PEER)/ccx_peer.py $(CALCULIX_STAMP) | $(VENV_STAMP)
	@mkdir -p $$(@D)
	$(PY) $(CALCULIX_PEER)/ccx_peer.py scenes/cantilever_static.toml \
	  $(if $(filter base,$(1)),,--preset $(1)) --work $$(@D)/ccx > $$@.tmp && mv $$@.tmp $$@
endef
$(foreach l,$(COMPARE_FEM_LEVELS),$(eval $(call COMPARE_FEM_LEVEL,$(l))))

## The sleeper of seed 004 §4 at other edge lengths (geo/sleeper_type3.geo, h = 0.05 m
## by default: meshes/sleeper_type3.msh).
.PRECIOUS: meshes/sleeper_type3_h%.msh
meshes/sleeper_type3_h%.msh: geo/sleeper_type3.geo | $(VENV_STAMP)
	@mkdir -p $(@D)
	$(GMSH) $< $(GMSH_FLAGS) -setnumber h $* -o $@

SLEEPER_PRESETS := base winkler fine fine_winkler paper paper_winkler
sleeper-modes: $(SLEEPER_PRESETS:%=results/sleeper_modes/%/summary.json)
	@for p in $(SLEEPER_PRESETS); do \
	  $(PY) -c 'import json, sys; f = json.load(open(sys.argv[1]))["figures"]; \
	    v = f["vertical_bending_frequencies_hz"][:3]; r = f.get("vertical_rigid_body_frequencies_hz", []); \
	    print("%14s: %6d nodes, vertical bending %s Hz%s" % (sys.argv[2], f["nodes"], \
	      " / ".join("%.1f" % x for x in v), \
	      ("  (rigid bounce and pitch " + " / ".join("%.1f" % x for x in r) + " Hz)") if r else ""))' \
	    results/sleeper_modes/$$p/summary.json $$p; \
	done
results/sleeper_modes/%/summary.json: scenes/sleeper_modes.toml $(RELEASE)/ballast-fem meshes/sleeper_type3.msh meshes/sleeper_type3_h0.02.msh meshes/sleeper_type3_h0.01.msh
	$(RELEASE)/ballast-fem modes $< $(if $(filter base,$*),,--preset $*) --out $(@D)
