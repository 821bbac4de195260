# Thin wrapper over the CMake presets (CMakePresets.json). Every target installs what is
# missing first, so `make demo` and `make test` work on a fresh machine.
PRESET ?= release
BUILD  := build/$(PRESET)
PNEUMA := $(BUILD)/cli/pneuma
DEMO_SCENARIO ?= scenarios/quiet-breathing.yaml
DEMO_OUT ?= out/demo
# CI treats warnings as errors.
export PNEUMA_WERROR ?= $(if $(CI),ON,OFF)

.PHONY: all deps configure build demo test bench clean format

all: build

deps:
	@scripts/install-deps

configure: deps
	@cmake --preset $(PRESET) >/dev/null

build: configure
	@cmake --build --preset $(PRESET)

demo: build
	@$(PNEUMA) run $(DEMO_SCENARIO) -o $(DEMO_OUT)

test: build
	@ctest --preset $(PRESET)

bench: build
	@scripts/run-benchmarks $(BUILD)

format:
	@git ls-files '*.cpp' '*.h' | xargs clang-format -i

clean:
	@rm -rf build
