# Ballast stone family: meshes/stones/stone_NNN.msh from geo/stone.geo, one gmsh run per
# stone, with the parameters of row NNN of geo/stone_family.tsv (made once by
# tools/stone_family.py; see docs/stones.md). Included by the main Makefile, which
# defines GMSH and VENV_STAMP.

STONE_COUNT ?= 60
STONE_GEO := geo/stone.geo
STONE_TABLE := geo/stone_family.tsv
STONE_DIR := meshes/stones
STONE_IDS := $(shell seq -f '%03g' 1 $(STONE_COUNT))
STONE_MESHES := $(STONE_IDS:%=$(STONE_DIR)/stone_%.msh)

# The row of stone $(1) as gmsh options: "-setnumber NAME VALUE" for every column after
# the id, named by the table's header line; fails when the table has no such row.
stone_options = awk -F'\t' -v id=$(1) \
  '/^\#/ {next} $$1 == "id" {for (i = 2; i <= NF; i++) name[i] = $$i; next} \
   $$1 == id {for (i = 2; i <= NF; i++) printf "-setnumber %s %s ", name[i], $$i; found = 1} \
   END {if (!found) {print "no stone " id " in $(STONE_TABLE)" > "/dev/stderr"; exit 1}}' $(STONE_TABLE)

.PHONY: stones
stones: $(STONE_MESHES)

$(STONE_DIR)/stone_%.msh: $(STONE_GEO) $(STONE_TABLE) | $(VENV_STAMP)
	@mkdir -p $(@D)
	@echo "gmsh stone_$*"
	@options="$$($(call stone_options,$*))" && \
	$(GMSH) $(STONE_GEO) -3 -format msh41 -v 2 -setnumber General.AbortOnError 2 \
	  $$options -o $@.tmp.msh && mv $@.tmp.msh $@
