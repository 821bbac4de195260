# Thin wrapper over the CMake presets (CMakePresets.json). Every target installs what is
# missing first, so `make demo` and `make test` work on a fresh machine.
PRESET ?= release
BUILD  := build/$(PRESET)
PNEUMA := $(BUILD)/cli/pneuma
DEMO_SCENARIO ?= scenarios/quiet-breathing.yaml
DEMO_OUT ?= out/demo
# ccache keys on paths relative to the checkout, so a second clone reuses the first one's objects.
export CCACHE_BASEDIR ?= $(CURDIR)
# CI treats warnings as errors.
export PNEUMA_WERROR ?= $(if $(CI),ON,OFF)

# The benchmarks are built with the release preset only (the presets say so for the others).
BUILD_BENCH ?= $(if $(filter release,$(PRESET)),ON,OFF)

# make install PREFIX=...: the CLI, its presets and the Python module (cmake --install).
PREFIX ?= /usr/local

.PHONY: all deps deps-demo configure configure-demo configure-full build demo test bench install deb clean format check-format

all: build

deps:
	@scripts/install-deps

# `make demo` installs and builds only what `pneuma run` needs (no test tools, Chromium or
# clang; only the executable, phantom-only: PNEUMA_PHANTOM_ONLY leaves out the label-map, repair
# and Mesh_3 units the demo never calls); `make test` adds the rest to the same build folder.
deps-demo:
	@scripts/install-deps --demo

configure-demo: deps-demo
	@cmake --preset $(PRESET) -DPNEUMA_BUILD_TESTS=OFF -DPNEUMA_BUILD_BENCH=OFF -DPNEUMA_PHANTOM_ONLY=ON >/dev/null

configure: deps
	@cmake --preset $(PRESET) -DPNEUMA_BUILD_TESTS=ON -DPNEUMA_BUILD_BENCH=$(BUILD_BENCH) -DPNEUMA_PHANTOM_ONLY=OFF >/dev/null

build: configure
	@cmake --build --preset $(PRESET)

demo: configure-demo
	@cmake --build --preset $(PRESET) --target pneuma
	@$(PNEUMA) run $(DEMO_SCENARIO) -o $(DEMO_OUT)

test: build
	@ctest --preset $(PRESET)

# What is installed is the whole engine: a folder `make demo` configured (phantom-only) is
# switched back, keeping its tests setting; a new one gets neither tests nor benchmarks.
configure-full:
	@test -f $(BUILD)/build.ninja || scripts/install-deps --demo
	@if [ -f $(BUILD)/build.ninja ]; then cmake --preset $(PRESET) -DPNEUMA_PHANTOM_ONLY=OFF >/dev/null; \
	else cmake --preset $(PRESET) -DPNEUMA_BUILD_TESTS=OFF -DPNEUMA_BUILD_BENCH=OFF -DPNEUMA_PHANTOM_ONLY=OFF >/dev/null; fi

# Builds only what is installed (the CLI and the Python module) in the configured build folder.
install: configure-full
	@cmake --build --preset $(PRESET) --target installables
	@cmake --install $(BUILD) --prefix $(PREFIX)

# build/<preset>/pneuma_<version>_<arch>.deb (installs into /usr; apt-get install ./that.deb).
deb: configure-full
	@cmake --build --preset $(PRESET) --target installables
	@cd $(BUILD) && cpack -G DEB

bench: build
	@scripts/run-benchmarks $(BUILD)

# The style is the committed .clang-format (none found: change nothing rather than guess).
format:
	@git ls-files '*.cpp' '*.h' | xargs clang-format -i --style=file --fallback-style=none

check-format:
	@scripts/check-format

clean:
	@rm -rf build
