# QDEM track impact (issue #8, seed 004 §4): the Type-3 sleeper on a ballast bed under
# train loads. `make track` packs the quick bed (ballast-pack impact-quick), writes a
# train load (ballast-post train-load: the first bogie of one car at 115 km/h), runs the
# quick track scene and draws its spectra and histories (ballast-post spectra). The
# default `make` ends with it. Included by the main Makefile (RELEASE, STONE_MESHES,
# TRACK_SLEEPER), after mk/track-load.mk (TRACK_LOAD, TRACK_PAPER_LOAD).

TRACK_BED := results/bed-impact-quick/packing.toml
# TRACK_SLEEPER, the Type-3 sleeper meshed at 25 mm, is defined by the main Makefile
# before the fragments (mk/pack.mk names it too).
TRACK_QUICK := results/track_impact-quick/summary.json
TRACK_SPECTRA := results/track_impact_quick.json

.PHONY: track
track: $(TRACK_SPECTRA)
meshes/sleeper_type3_h%.msh: geo/sleeper_type3.geo | $(VENV_STAMP)
	$(GMSH_H)
$(TRACK_BED): scenes/bed.toml $(STONE_MESHES) $(TRACK_SLEEPER) | $(RELEASE)/ballast-pack
	$(RELEASE)/ballast-pack $< --preset impact-quick --out $(@D)
$(TRACK_QUICK): scenes/track_impact.toml $(TRACK_BED) $(TRACK_LOAD) $(RUST_SOURCES) | $(RELEASE)/ballast-qdem
	$(RELEASE)/ballast-qdem $< --preset quick --out $(@D)
$(TRACK_SPECTRA): $(TRACK_QUICK) | $(RELEASE)/ballast-post
	$(RELEASE)/ballast-post spectra $(dir $<)sensors.csv --load $(TRACK_LOAD) --out $(@:.json=)

## Studies on the quick bed (minutes each, not in tests; `make track-study`):
## - friction (seed 004 §4.1): the first bogie's whole passage (0.2 s, the load back to
##   zero) with µ = 0.577 and µ = 1.73 on every contact; the settlements side by side;
## - the stone model: the quick run (0.07 s) with rigid stones, stones deformable within
##   0.15 m of the sleeper, and all stones deformable (seed 004's model, the
##   reference): sleeper spectrum difference against wall time.
TRACK_STUDY := results/track-study
TRACK_MU := 0.577 1.73
TRACK_STONES := deformable near rigid
.PHONY: track-study bench-track
track-study: $(TRACK_STUDY)/friction.md $(TRACK_STUDY)/stones.md
$(TRACK_STUDY)/mu-%/summary.json: scenes/track_impact.toml $(TRACK_BED) $(TRACK_LOAD) | $(RELEASE)/ballast-qdem
	$(RELEASE)/ballast-qdem $< --preset quick --set 'track.duration="0.2 s"' \
	  --set friction.ballast_ballast=$* --set friction.ballast_sleeper=$* \
	  --set friction.base=$* --out $(@D)
$(TRACK_STUDY)/stones-%/summary.json: scenes/track_impact.toml $(TRACK_BED) $(TRACK_LOAD) | $(RELEASE)/ballast-qdem
	$(RELEASE)/ballast-qdem $< --preset quick --set 'track.stones="$*"' \
	  $(if $(filter near,$*),--set 'track.deformable_within="0.15 m"') --out $(@D)
$(TRACK_STUDY)/friction.md: $(TRACK_MU:%=$(TRACK_STUDY)/mu-%/summary.json) | $(RELEASE)/ballast-post
	$(RELEASE)/ballast-post track-compare $(TRACK_MU:%=$(TRACK_STUDY)/mu-%) --out $(@:.md=)
$(TRACK_STUDY)/stones.md: $(TRACK_STONES:%=$(TRACK_STUDY)/stones-%/summary.json) | $(RELEASE)/ballast-post
	$(RELEASE)/ballast-post track-compare $(TRACK_STONES:%=$(TRACK_STUDY)/stones-%) --out $(@:.md=)

## Settlement against friction over many beds and trains (`make track-mu-ensemble`,
## seed 004 §4.1): TRACK_MU_SEEDS impact-quick beds (seeds 1..N) × TRACK_MU_SPEEDS
## trains, the first bogie over the sleeper at µ = 0.577 and 1.73 (the quick scene, 2
## threads, ≈ 1.5 min a run); the table and the paired statistics go to
## results/track-mu-ensemble.md. Beds, loads and runs already there are reused.
TRACK_MU_SEEDS ?= 6
TRACK_MU_SPEEDS ?= 115
.PHONY: track-mu-ensemble
track-mu-ensemble: scenes/track_impact.toml scenes/bed.toml $(STONE_MESHES) $(TRACK_SLEEPER) | $(RELEASE)/ballast-pack $(RELEASE)/ballast-qdem $(RELEASE)/ballast-post $(VENV_STAMP)
	$(PY) tools/track_ensemble.py --pack $(RELEASE)/ballast-pack --qdem $(RELEASE)/ballast-qdem \
	  --post $(RELEASE)/ballast-post --seeds $(TRACK_MU_SEEDS) --speeds "$(TRACK_MU_SPEEDS)" \
	  --out results/track-mu-ensemble | tee results/track-mu-ensemble.md

# The paper preset's bed (its scene reads this file): `make results/bed-impact/summary.json`.
TRACK_PAPER_BED := results/bed-impact/packing.toml

## The first bogie (the quick load, 0.2 s) on the paper bed (`make track-paper-bogie`):
## seed 004's bed and time step (≈ 0.1 µs) with rigid stones, ≈ 2 M steps, hours on 2
## cores; a killed run (a checkpoint and no summary) resumes where it stopped. Its
## spectra go to results/track_impact_paper_bogie*.
TRACK_PAPER_BOGIE := results/track_impact-paper-bogie/summary.json
TRACK_PAPER_BOGIE_ARGS := --preset paper --set 'track.loads="../$(TRACK_LOAD)"' \
  --set 'track.duration="0.2 s"'
.PHONY: track-paper-bogie
track-paper-bogie: results/track_impact_paper_bogie.json
$(TRACK_PAPER_BOGIE): scenes/track_impact.toml $(TRACK_PAPER_BED) $(TRACK_LOAD) | $(RELEASE)/ballast-qdem
	$(call resume_or_run,$(@D),$(RELEASE)/ballast-qdem $< $(TRACK_PAPER_BOGIE_ARGS))
results/track_impact_paper_bogie.json: $(TRACK_PAPER_BOGIE) | $(RELEASE)/ballast-post
	$(RELEASE)/ballast-post spectra $(dir $<)sensors.csv --load $(TRACK_LOAD) --out $(@:.json=)

## The paper preset as published (`make track-paper`): the five cars of the default
## train load (3.5 s) on the paper bed, 5.8 M steps: ≈ 1.4 h on 2 idle cores (≈ 1 200
## steps/s on 2026-12-07).
## A checkpoint every 50 000 steps (30 ms); a killed run resumes where it stopped, so
## it can be run in pieces, e.g. `nice -n 19 make track-paper TRACK_PAPER_THREADS=1`
## beside other work. Its spectra go to results/track_impact_paper*, its settlement
## bogie by bogie (and its histories) to results/track_impact_paper_passages*.
TRACK_PAPER := results/track_impact-paper/summary.json
TRACK_PAPER_THREADS ?= 2
.PHONY: track-paper
track-paper: results/track_impact_paper.json results/track_impact_paper_passages.md
results/track_impact_paper_passages.md: $(TRACK_PAPER) | $(RELEASE)/ballast-post
	$(RELEASE)/ballast-post track-compare $(<D) --out $(@:.md=)
$(TRACK_PAPER): scenes/track_impact.toml $(TRACK_PAPER_BED) $(TRACK_PAPER_LOAD) | $(RELEASE)/ballast-qdem
	$(call resume_or_run,$(@D),$(RELEASE)/ballast-qdem $< --preset paper --threads $(TRACK_PAPER_THREADS))
results/track_impact_paper.json: $(TRACK_PAPER) | $(RELEASE)/ballast-post
	$(RELEASE)/ballast-post spectra $(dir $<)sensors.csv --load $(TRACK_PAPER_LOAD) --out $(@:.json=)

## The paper preset at seed 004's other friction (`make track-paper-mu`): the same five
## cars with µ = 1.73 on every contact (seed 004 §4.1, Figure 8's dashed lines), a run
## of hours like `make track-paper` and resumable the same way; then the two runs side
## by side (results/track_impact_paper_friction.md: settlement, lateral motion).
TRACK_PAPER_MU := results/track_impact-paper-mu1.73/summary.json
.PHONY: track-paper-mu
track-paper-mu: results/track_impact_paper_friction.md
$(TRACK_PAPER_MU): scenes/track_impact.toml $(TRACK_PAPER_BED) $(TRACK_PAPER_LOAD) | $(RELEASE)/ballast-qdem
	$(call resume_or_run,$(@D),$(RELEASE)/ballast-qdem $< --preset paper --threads $(TRACK_PAPER_THREADS) \
	  --set friction.ballast_ballast=1.73 --set friction.ballast_sleeper=1.73 --set friction.base=1.73)
results/track_impact_paper_friction.md: $(TRACK_PAPER) $(TRACK_PAPER_MU) | $(RELEASE)/ballast-post
	$(RELEASE)/ballast-post track-compare $(^D) --out $(@:.md=)

## Throughput of the track scene (part of `make bench`): 20 ms of the quick preset on 1
## and 2 threads (the files must agree: spectrum difference 0), with peak memory.
## TRACK_BENCH_PRESET=paper benchmarks the paper bed (needs results/bed-impact:
## `make results/bed-impact/summary.json`, hours); there a step costs ≈ 20 × the quick
## one, so TRACK_BENCH_SETTLE and TRACK_BENCH_DURATION (the scene's settle, 20 ms, and
## 20 ms by default) shorten it, e.g. TRACK_BENCH_SETTLE="2 ms" TRACK_BENCH_DURATION="2 ms".
TRACK_BENCH_PRESET ?= quick
TRACK_BENCH_DURATION ?= 20 ms
TRACK_BENCH_SETTLE ?=
TRACK_BENCH := results/bench-track-$(TRACK_BENCH_PRESET)
TRACK_BENCH_INPUTS := $(if $(filter paper,$(TRACK_BENCH_PRESET)),$(TRACK_PAPER_BED) $(TRACK_PAPER_LOAD),$(TRACK_BED) $(TRACK_LOAD))
bench: bench-track
bench-track: scenes/track_impact.toml $(TRACK_BENCH_INPUTS) | $(RELEASE)/ballast-qdem $(RELEASE)/ballast-post
	for t in 1 2; do \
	  $(RELEASE)/ballast-qdem $< --preset $(TRACK_BENCH_PRESET) --threads $$t \
	    --set 'track.duration="$(TRACK_BENCH_DURATION)"' --set track.frames=1 \
	    $(if $(TRACK_BENCH_SETTLE),--set 'track.settle="$(TRACK_BENCH_SETTLE)"') \
	    --out $(TRACK_BENCH)/threads-$$t || exit 1; \
	done
	$(RELEASE)/ballast-post track-compare $(TRACK_BENCH)/threads-1 $(TRACK_BENCH)/threads-2 --out $(TRACK_BENCH)/bench
