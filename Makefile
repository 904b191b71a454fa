# ballast: geometry -> meshes -> solvers -> VTK/CSV -> charts.
#
#   make          set up what is missing, build, mesh everything, run the default scenes
#                 (mesh gallery, the QDEM quick scenes and their chart, the quick
#                 ballast bed of ballast-pack and its chart, then the quick tamping
#                 cycle of ballast-nscd on that bed and its chart)
#   make test     set up, check formatting, build with clippy's lints, run every test
#   make lint     clippy alone on every target
#   make meshes   mesh every geo/*.geo and the stone family
#   make paper    the QDEM scenes at the paper's resolution and the convergence table
#   make bench    QDEM throughput at paper resolution, NSCD throughput and the DDM
#                 efficiency (quick bed), each on 1 and 2 threads; the NLGS sweep alone
#                 on a synthetic problem; the seed's Table 3 tamping case in its three
#                 versions (hours; needs the table3 bed)
#   make clean    remove build outputs, meshes and results (keeps the venv)
#
# Every step has real file dependencies: a second `make` does nothing. The default
# scenes depend on the Rust sources, with the binaries order-only: `make test` relinks
# the binaries (cargo unifies the dev-dependencies' features into them), which must not
# make the next `make` redo every scene.

SHELL := /bin/bash
.DEFAULT_GOAL := all
.DELETE_ON_ERROR:

PYTHON3 ?= python3
CARGO ?= cargo
VENV := .venv
PY := $(VENV)/bin/python
VENV_STAMP := $(VENV)/.installed
# The gmsh wheel's bin/gmsh is a Python script: run it with the venv's python.
GMSH := $(PY) $(VENV)/bin/gmsh
# The CLI exits 0 on a .geo syntax error unless told to abort on errors.
GMSH_FLAGS := -3 -format msh41 -setnumber General.AbortOnError 2 -v 2

RELEASE := target/release
BINARIES := $(addprefix $(RELEASE)/,ballast-pack ballast-nscd ballast-qdem ballast-fem ballast-post)
RUST_SOURCES := $(shell find src -name '*.rs') Cargo.toml Cargo.lock

# Objects meshed from geo/ by the pattern rule (the stone is meshed per family member).
OBJECT_MESHES := $(patsubst geo/%.geo,meshes/%.msh,$(filter-out geo/stone.geo,$(wildcard geo/*.geo)))

export BALLAST_PYTHON := $(abspath $(PY))

# A long run into directory $(1) by command $(2) (the tool and its scene arguments):
# resumed from its checkpoint when a killed run left one and no summary, else run.
resume_or_run = if [ -f $(1)/checkpoint.bin ] && [ ! -f $(1)/summary.json ]; then \
	    $(2) --resume $(1); else $(2) --out $(1); fi

# Meshes that several fragments name as prerequisites come first: make expands a rule's
# prerequisites as it reads the rule, so a list defined in a fragment read later would be
# empty there (on a fresh machine `make results/bed-quick/summary.json` then ran
# ballast-pack before any stone was meshed). tests/makefile.rs checks this.
include mk/stones.mk
# The Type-3 sleeper meshed at 25 mm for the track beds: its 24 mm contact spheres then
# cover its faces (at the 5 cm of meshes/sleeper_type3.msh a stone's sphere passes
# between them; seed 004's mesh has 10 mm edges).
TRACK_SLEEPER := meshes/sleeper_type3_h0.025.msh

# Fragments: Debian packages, peer comparisons, one file per tool's scenes.
include $(sort $(filter-out mk/stones.mk,$(wildcard mk/*.mk)))

.PHONY: all setup build meshes gallery test lint clean distclean readme-figure

all: gallery qdem-quick $(QDEM_CHART) pack-quick tamping track pack-periodic tamping-drives

## Set-up: Debian packages the build links (mk/system-deps.mk) and a project-local venv
## with the pinned Python tools.
setup: $(SYSTEM_DEPS_STAMP) $(VENV_STAMP)
$(VENV_STAMP): tools/requirements.txt
	@test -x $(PY) || $(PYTHON3) -m venv $(VENV)
	$(PY) -m pip install --quiet --disable-pip-version-check -r tools/requirements.txt
	@touch $@

## Build: the release binaries (cargo only runs when a source changed).
build: $(BINARIES)
$(BINARIES) &: $(RUST_SOURCES) | $(SYSTEM_DEPS_STAMP)
	$(CARGO) build --release --locked --bins
	@touch $(BINARIES)

## Meshes: one rule for every parameterised gmsh source, and GMSH_H for the rules of
## variants meshed at edge length h = the stem (meshes/<name>_h<h>.msh, mk/*.mk).
meshes: $(OBJECT_MESHES) stones
meshes/%.msh: geo/%.geo | $(VENV_STAMP)
	@mkdir -p $(@D)
	$(GMSH) $< $(GMSH_FLAGS) -o $@
define GMSH_H
@mkdir -p $(@D)
$(GMSH) $< $(GMSH_FLAGS) -setnumber h $* -o $@
endef

## The default scene: every mesh checked, exported to VTK and tabulated.
gallery: results/mesh_gallery/summary.json
results/mesh_gallery/summary.json: scenes/mesh_gallery.toml $(OBJECT_MESHES) $(STONE_MESHES) $(RUST_SOURCES) | $(RELEASE)/ballast-post
	$(RELEASE)/ballast-post meshes $< --out $(@D)

## README pictures: the meshes rendered from the gallery's VTK files, the QDEM quick
## chart, and the speed/accuracy chart when `make speed-accuracy` has run.
readme-figure: docs/img/meshes.png docs/img/qdem_quick.png docs/img/bed_quick.png docs/img/bed_quick_compactness.png docs/img/tamping_quick.png
	@if [ -f results/speed_accuracy/chart.png ]; then cp results/speed_accuracy/chart.png docs/img/speed_accuracy.png; fi
docs/img/qdem_quick.png: $(QDEM_CHART)
	@mkdir -p $(@D)
	cp $< $@
docs/img/tamping_quick.png: $(TAMPING_CHART)
	@mkdir -p $(@D)
	cp $< $@
docs/img/bed_quick.png: $(PACK_CHART)
	@mkdir -p $(@D)
	cp $< $@
docs/img/bed_quick_compactness.png: $(PACK_DEPTH_CHART)
	@mkdir -p $(@D)
	cp $< $@
docs/img/meshes.png: tools/render_meshes.py results/mesh_gallery/summary.json | $(VENV_STAMP)
	@mkdir -p $(@D)
	$(PY) $< results/mesh_gallery $@

## Tests: formatting, then every test target built with clippy's lints (warnings denied)
## by tools/clippy-rustc, so the test build is the lint pass (a separate `cargo clippy`
## took 2.5 min of CI), then every test (they read what the real tools write). The build
## needs no meshes, so a sub-make runs it beside the set-up and gmsh (two jobs: on the
## 2-core CI runner cargo builds while gmsh meshes).
LINTED_CARGO := RUSTC_WORKSPACE_WRAPPER=$(abspath tools/clippy-rustc) $(CARGO)
.PHONY: test-build test-inputs
test:
	$(MAKE) -j2 test-build test-inputs
	$(LINTED_CARGO) test --release --locked
test-build: $(SYSTEM_DEPS_STAMP)
	$(CARGO) fmt --check
	$(LINTED_CARGO) test --release --locked --no-run
test-inputs: $(OBJECT_MESHES) $(QDEM_QUICK_MESHES) $(TRACK_SLEEPER) $(STONE_MESHES)

## Lints alone (what the test build checks), with clippy's own command.
lint:
	$(CARGO) clippy --release --locked --all-targets -- -D warnings

clean:
	$(CARGO) clean
	rm -rf results meshes/*.msh meshes/stones

distclean: clean
	rm -rf $(VENV)
