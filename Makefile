# Everyday commands. On a fresh Debian 12 machine (no make yet) start with
# scripts/setup.sh demo|test, which installs the packages and then runs these.
BUILD_DIR ?= build
JOBS ?= $(shell nproc)
CMAKE_FLAGS ?= -DCMAKE_BUILD_TYPE=Release

.PHONY: all deps configure build demo test bench charts ui-screenshots clean

all: build

deps:
	./scripts/install-deps.sh

# Tests and benchmarks on explicitly: a tree `make demo` configured has them off.
configure:
	cmake -S . -B $(BUILD_DIR) -DPHOTORIG_BUILD_TESTS=ON -DPHOTORIG_BUILD_BENCH=ON $(CMAKE_FLAGS)

build: configure
	cmake --build $(BUILD_DIR) -j $(JOBS)

# What the demo runs: the CLI, and the Python module (docs/python.md) to explore its run.
DEMO_TARGETS ?= photorig photorig_python

# The main job: capture the sphere recipe on the simulated dome and reconstruct its normals.
# Installs the demo's packages only (scripts/install-deps.sh demo), which have no GoogleTest
# or Google Benchmark, and builds only the demo's targets; `make build` (and `make test`)
# build everything.
demo:
	./scripts/install-deps.sh demo
	cmake -S . -B $(BUILD_DIR) -DPHOTORIG_BUILD_TESTS=OFF -DPHOTORIG_BUILD_BENCH=OFF $(CMAKE_FLAGS)
	cmake --build $(BUILD_DIR) -j $(JOBS) --target $(DEMO_TARGETS)
	rm -rf runs/demo
	$(BUILD_DIR)/bin/photorig run config/recipes/ps-sphere.yaml --out runs/demo

# Every test, through CTest.
test: deps
	$(MAKE) build
	cd $(BUILD_DIR) && ctest --output-on-failure -j $(JOBS) --timeout 600

bench: build
	./scripts/run-benchmarks.sh $(BUILD_DIR)

charts: build
	./scripts/charts.sh $(BUILD_DIR)

# The browser interface's screenshots in docs/screenshots/ (docs/ui.md), from its test.
ui-screenshots: build
	/usr/bin/python3 tests/browser/test_browser_ui.py --bin-dir $(BUILD_DIR)/bin --source-dir . \
	  --artefacts $(BUILD_DIR)/tests/browser/artefacts --screenshots docs/screenshots

clean:
	rm -rf $(BUILD_DIR)
