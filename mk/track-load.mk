# The train loads of the track scenes (issue #8): `ballast-post train-load` records
# (time_s, Rp1, Rp2) that scenes/track_impact.toml reads. They live in their own file,
# and depend on it alone, because the paper runs that read them take hours: editing
# mk/track.mk must not rewrite a load and so restart them. Included by the main Makefile
# before mk/track.mk.

# The quick preset's load: one car's leading bogie, the first axle 1.885 m (3π/4 L, a
# zero of the influence line) before the sleeper, 0.2 s of record.
TRACK_LOAD := results/train-load-quick/train_load.csv
$(TRACK_LOAD): mk/track-load.mk | $(RELEASE)/ballast-post
	$(RELEASE)/ballast-post train-load --out $@ --cars 1 --lead-in-m 1.885 --duration-s 0.2

# The paper preset's load: the whole train of `ballast-post train-load`'s defaults (five
# cars at 115 km/h; the last axle is 8 m past the sleeper at 3.39 s), recorded to the
# scene's 3.5 s (seed 004 Fig. 5's record).
TRACK_PAPER_LOAD := results/train-load/train_load.csv
$(TRACK_PAPER_LOAD): mk/track-load.mk | $(RELEASE)/ballast-post
	$(RELEASE)/ballast-post train-load --out $@ --duration-s 3.5
