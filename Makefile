# Thin wrapper over the CMake presets (CMakePresets.json). Every target installs what is
# missing first, so `make demo` and `make test` work on a fresh machine.
PRESET ?= release
BUILD  := build/$(PRESET)
# make demo's own folder: a phantom-only build (PNEUMA_PHANTOM_ONLY) that `make build` and
# `make test` never switch back and forth.
DEMO_BUILD := build/demo-$(PRESET)
PNEUMA := $(DEMO_BUILD)/cli/pneuma
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

.PHONY: all deps deps-demo configure configure-demo configure-installables build demo test bench install deb clean format check-format

all: build

deps:
	@scripts/install-deps

# `make demo` installs and builds only what `pneuma run` on the built-in phantom needs (no test
# tools, Chromium or clang, no ITK or DCMTK; only the executable, without the label-map, image,
# DICOM, repair and Mesh_3 code the phantom never calls, each library one unity source:
# BENCHMARKS.md, goal 4 of #50);
# `make test` builds the whole engine and the rest in build/$(PRESET).
deps-demo:
	@scripts/install-deps --demo

configure-demo: deps-demo
	@cmake --preset $(PRESET) -B $(DEMO_BUILD) -DPNEUMA_BUILD_TESTS=OFF -DPNEUMA_BUILD_BENCH=OFF \
	  -DPNEUMA_PHANTOM_ONLY=ON >/dev/null

configure: deps
	@cmake --preset $(PRESET) -DPNEUMA_BUILD_TESTS=ON -DPNEUMA_BUILD_BENCH=$(BUILD_BENCH) >/dev/null

build: configure
	@cmake --build --preset $(PRESET)

demo: configure-demo
	@cmake --build $(DEMO_BUILD) --target pneuma
	@$(PNEUMA) run $(DEMO_SCENARIO) -o $(DEMO_OUT)

test: build
	@ctest --preset $(PRESET)

# A folder not configured yet gets the whole engine without tests or benchmarks.
configure-installables:
	@test -f $(BUILD)/build.ninja || { scripts/install-deps --engine && \
	  cmake --preset $(PRESET) -DPNEUMA_BUILD_TESTS=OFF -DPNEUMA_BUILD_BENCH=OFF >/dev/null; }

# Builds only what is installed (the CLI and the Python module) in the configured build folder.
install: configure-installables
	@cmake --build --preset $(PRESET) --target installables
	@cmake --install $(BUILD) --prefix $(PREFIX)

# build/<preset>/pneuma_<version>_<arch>.deb (installs into /usr; apt-get install ./that.deb).
deb: configure-installables
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
