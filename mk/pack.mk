# ballast-pack (issue #6): ballast beds by gravity deposition, scenes/bed.toml. The quick
# preset and its chart end the default `make`; the larger presets are long runs.
# Included by the main Makefile, which defines PY, RELEASE, STONE_MESHES, VENV_STAMP.

PACK_QUICK := results/bed-quick/summary.json
PACK_CHART := results/bed_quick.png
# The quick bed's compactness by depth below each control box's top (ballast-post
# compactness: the loose band under the sleepers apart from the bulk).
PACK_DEPTH_CHART := results/bed_quick_compactness.png
# What each phase's solve did (steps on the sweep cap, energy rises) and where the last
# step left it (tools/pack_report.py settle).
PACK_SETTLE := results/bed_quick_settle.md
PACK_PRESETS := table3 tamping7 impact
PACK_PERIODIC := results/bed-quick-periodic/summary.json
PACK_PERIODIC_CHART := results/bed_quick_periodic.png

.PHONY: pack-quick pack-periodic pack-presets

pack-quick: $(PACK_CHART) $(PACK_DEPTH_CHART) $(PACK_SETTLE)
$(PACK_QUICK): scenes/bed.toml $(STONE_MESHES) meshes/sleeper_type3.msh $(RUST_SOURCES) | $(RELEASE)/ballast-pack
	$(RELEASE)/ballast-pack $< --preset quick --out $(@D)
$(PACK_CHART): tools/pack_report.py $(PACK_QUICK) | $(VENV_STAMP)
	$(PY) $< chart $(dir $(PACK_QUICK)) $@
$(PACK_SETTLE): tools/pack_report.py $(PACK_QUICK) | $(VENV_STAMP)
	$(PY) $< settle $(dir $(PACK_QUICK)) > $@.tmp && mv $@.tmp $@
$(PACK_DEPTH_CHART): $(PACK_QUICK) | $(RELEASE)/ballast-post
	$(RELEASE)/ballast-post compactness $(<D) --out $(@:.png=)

## The quick bed periodic along the track (bed.sides = "periodic"): the default `make`
## ends with it.
pack-periodic: $(PACK_PERIODIC_CHART)
$(PACK_PERIODIC): scenes/bed.toml $(STONE_MESHES) $(RUST_SOURCES) | $(RELEASE)/ballast-pack
	$(RELEASE)/ballast-pack $< --preset quick-periodic --out $(@D)
$(PACK_PERIODIC_CHART): tools/pack_report.py $(PACK_PERIODIC) | $(VENV_STAMP)
	$(PY) $< chart $(dir $(PACK_PERIODIC)) $@

## The seed-sized beds (hours each on 2 cores): `make pack-presets`, not part of tests.
## A bed whose run was killed (a checkpoint and no summary) resumes where it stopped:
## `make results/bed-impact/summary.json` again continues it.
pack-presets: $(PACK_PRESETS:%=results/bed-%/summary.json) | $(VENV_STAMP)
	$(PY) tools/pack_report.py table $(PACK_QUICK:%/summary.json=%) $(^:%/summary.json=%)
	for d in $(^:%/summary.json=%); do $(PY) tools/pack_report.py settle $$d; done
# The tamping7 bed is its bay laid seven times and more along the slice (scenes/bed.toml).
results/bed-tamping7/summary.json: results/bed-tamping7-bay/summary.json
# The packing comes with the summary: one run writes both (a pattern rule's targets are
# made together). The packing is written a moment before the summary, so a rule
# "packing: summary" would count it out of date and make `make -n` list every run that
# reads the bed, hours of them, as to be redone.
results/bed-%/summary.json results/bed-%/packing.toml: scenes/bed.toml $(STONE_MESHES) meshes/sleeper_type3.msh $(TRACK_SLEEPER) | $(RELEASE)/ballast-pack
	$(call resume_or_run,$(@D),$(RELEASE)/ballast-pack $< --preset $*)
