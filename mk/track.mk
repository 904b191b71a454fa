# QDEM track impact (issue #8, seed 004 §4): the Type-3 sleeper on a ballast bed under
# train loads. `make track` packs the quick bed (ballast-pack impact-quick), writes a
# train load (ballast-post train-load: the first bogie of one car at 115 km/h), runs the
# quick track scene and draws its spectra and histories (ballast-post spectra). The
# default `make` ends with it. Included by the main Makefile (RELEASE, STONE_MESHES).

TRACK_BED := results/bed-impact-quick/packing.toml
TRACK_LOAD := results/train-load-quick/train_load.csv
TRACK_QUICK := results/track_impact-quick/summary.json
TRACK_SPECTRA := results/track_impact_quick.json

.PHONY: track
track: $(TRACK_SPECTRA)
$(TRACK_BED): scenes/bed.toml $(STONE_MESHES) meshes/sleeper_type3.msh | $(RELEASE)/ballast-pack
	$(RELEASE)/ballast-pack $< --preset impact-quick --out $(@D)
# One car's leading bogie: the first axle 1.885 m (3π/4 L, a zero of the influence
# line) before the sleeper, 0.2 s of record.
$(TRACK_LOAD): | $(RELEASE)/ballast-post
	$(RELEASE)/ballast-post train-load --out $@ --cars 1 --lead-in-m 1.885 --duration-s 0.2
$(TRACK_QUICK): scenes/track_impact.toml $(TRACK_BED) $(TRACK_LOAD) $(RUST_SOURCES) | $(RELEASE)/ballast-qdem
	$(RELEASE)/ballast-qdem $< --preset quick --out $(@D)
$(TRACK_SPECTRA): $(TRACK_QUICK) | $(RELEASE)/ballast-post
	$(RELEASE)/ballast-post spectra $(dir $<)sensors.csv --load $(TRACK_LOAD) --out $(@:.json=)
