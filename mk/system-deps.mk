# Debian packages the build needs: fonts-dejavu-core (the charts' font), libhdf5-dev (linked by hdf5-metno for the FCLIB .hdf5
# reader) and pkg-config (which finds it). `build` and `test` depend on the stamp.
# Installs only what is missing; needs root (CI and the developers' machines are root).

SYSTEM_DEPS_STAMP := .system-deps

.PHONY: system-deps
system-deps: $(SYSTEM_DEPS_STAMP)

$(SYSTEM_DEPS_STAMP): mk/system-deps.mk
	dpkg -s libhdf5-dev pkg-config fonts-dejavu-core >/dev/null 2>&1 || \
	  (apt-get update && DEBIAN_FRONTEND=noninteractive apt-get install -y libhdf5-dev pkg-config fonts-dejavu-core)
	@touch $@
