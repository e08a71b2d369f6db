# qogi: `make demo` and `make test` do all set-up on a fresh Debian machine
# (system packages, .venv, the package built and installed), then their job.
# Stamp files under build/stamps keep a second run from redoing set-up; any
# changed C++/CMake source triggers an incremental rebuild of build/cmake.

SHELL      := /bin/bash
PYTHON     ?= python3
VENV       := .venv
VPY        := $(VENV)/bin/python
BUILD      := build/cmake
INSTALL    := build/install
STAMPS     := build/stamps
JOBS       ?= $(shell nproc 2>/dev/null || echo 2)
export CMAKE_BUILD_PARALLEL_LEVEL := $(JOBS)
# ccache (installed by the set-up): paths are hashed relative to the checkout, so a
# fresh clone, a worktree or the wheel's build reuse the objects already compiled.
CCACHE     := $(shell command -v ccache 2>/dev/null)
ifneq ($(CCACHE),)
export CMAKE_CXX_COMPILER_LAUNCHER := $(CCACHE)
export CCACHE_BASEDIR := $(CURDIR)
export CCACHE_NOHASHDIR := 1
endif

ENGINE_SOURCES := $(shell find cpp cmake -type f 2>/dev/null) CMakeLists.txt pyproject.toml
CONSUMER_SOURCES := $(shell find examples/cpp_consumer -type f 2>/dev/null)

.PHONY: FORCE all setup build demo test test-cpp test-python consumer bench gui wheel check-clang fuzz lint clean distclean

all: build

setup: $(STAMPS)/pydeps

$(STAMPS):
	@mkdir -p $@

$(STAMPS)/system: scripts/setup_system.sh | $(STAMPS)
	PYTHON=$(PYTHON) scripts/setup_system.sh
	@touch $@

$(VPY): | $(STAMPS)/system
	$(PYTHON) -m venv $(VENV)

$(STAMPS)/pydeps: $(STAMPS)/system requirements/dev.txt requirements/constraints.txt | $(VPY)
	$(VPY) -m pip install -q --upgrade pip
	$(VPY) -m pip install -q -r requirements/dev.txt -c requirements/constraints.txt
	@touch $@

# The package in editable mode: Python sources are used in place; the
# extension and the C++ tests are built in $(BUILD) (incrementally).
# WERROR=ON (as CI sets it) makes warnings in qogi's own C++ errors.
# The setting is remembered in a stamp that changes only when the setting does,
# so switching it rebuilds (the objects compiled without -Werror are not reused
# as if they had passed with it).
WERROR ?= OFF
$(STAMPS)/werror: FORCE | $(STAMPS)
	@echo '$(WERROR)' | cmp -s - $@ || echo '$(WERROR)' > $@

$(STAMPS)/built: $(STAMPS)/pydeps $(STAMPS)/werror $(ENGINE_SOURCES)
	$(VPY) -m pip install -q --no-build-isolation --no-deps -e . \
	  -Cbuild-dir=$(BUILD) -Ccmake.define.QOGI_BUILD_TESTS=ON -Ccmake.define.QOGI_WERROR=$(WERROR)
	@# Type stubs of the extension for editors and mypy (generated, not committed).
	$(VENV)/bin/pybind11-stubgen qogi._engine -o build/stubs --ignore-all-errors >/dev/null \
	  && cp build/stubs/qogi/_engine.pyi python/qogi/_engine.pyi
	@touch $@

build: $(STAMPS)/built

demo: $(STAMPS)/built
	$(VENV)/bin/qogi demo

test: test-cpp consumer test-python

test-cpp: $(STAMPS)/built
	$(VENV)/bin/ctest --test-dir $(BUILD) --output-on-failure -j $(JOBS)

# The installed C++ package, and a vendor-style app built against it.
$(STAMPS)/consumer: $(STAMPS)/built $(CONSUMER_SOURCES)
	rm -rf $(INSTALL) build/consumer
	$(VENV)/bin/cmake --install $(BUILD) --prefix $(INSTALL) --component dev
	$(VENV)/bin/cmake -S examples/cpp_consumer -B build/consumer -G Ninja \
	  -DCMAKE_PREFIX_PATH=$(abspath $(INSTALL)) -DCMAKE_BUILD_TYPE=Release
	$(VENV)/bin/cmake --build build/consumer
	@touch $@

consumer: $(STAMPS)/consumer
	build/consumer/qogi_consumer

# The Python tests on PYTEST_WORKERS processes (pytest-xdist), a test file per
# process at a time (its module fixtures, the rendered scenes, built once);
# the slowest are listed at the end. PYTEST_WORKERS=0 runs them in this process.
# PYTEST_ARGS selects (e.g. PYTEST_ARGS='-m shared_data').
PYTEST_WORKERS ?= $(JOBS)
PYTEST_ARGS ?=
test-python: $(STAMPS)/built
	$(VPY) -m pytest -q -n $(PYTEST_WORKERS) --dist loadfile --durations=15 $(PYTEST_ARGS)

# Linters and the type checker (settings: pyproject.toml [tool.ruff]/[tool.mypy],
# .clang-format). Every check runs and reports; the target fails if any failed.
# mypy reads the extension's stubs written by the build. scripts/format.sh applies
# every mechanical fix (formatting, import order, ...).
CXX_SOURCES = $(shell find cpp examples/cpp_consumer -name '*.cc' -o -name '*.h' | sort)
lint: $(STAMPS)/built
	@status=0; \
	echo "lint: ruff check"; $(VENV)/bin/ruff check . || status=1; \
	echo "lint: ruff format --check"; \
	  $(VENV)/bin/ruff format --check --output-format concise . || status=1; \
	echo "lint: mypy"; $(VENV)/bin/mypy || status=1; \
	echo "lint: clang-format"; bad=0; \
	for f in $(CXX_SOURCES); do \
	  $(VENV)/bin/clang-format --dry-run --Werror "$$f" >/dev/null 2>&1 \
	    || { echo "$$f: would be reformatted"; bad=$$((bad + 1)); }; \
	done; \
	if [ $$bad -gt 0 ]; then echo "$$bad C++ files would be reformatted"; status=1; fi; \
	[ $$status -eq 0 ] && echo "lint: all checks passed" \
	  || echo "lint: failed (scripts/format.sh fixes formatting and import order)"; \
	exit $$status

# Coverage-guided fuzzing of the FLIR and recording readers, and of the writers
# on a nearly full file system (root: a tmpfs it mounts; skipped otherwise)
# (atheris), FUZZ_S seconds each; `make test` runs a bounded hypothesis fuzz
# (tests/python/test_fuzz.py, test_full_disk.py).
FUZZ_S ?= 600
fuzz: $(STAMPS)/built
	cd tests/fuzz && ../../$(VPY) run_fuzz.py flir -max_total_time=$(FUZZ_S)
	cd tests/fuzz && ../../$(VPY) run_fuzz.py recording -max_total_time=$(FUZZ_S)
	if [ "$$(id -u)" = 0 ]; then cd tests/fuzz && ../../$(VPY) run_fuzz.py writers \
	  -max_total_time=$(FUZZ_S); else echo "fuzz: writers on a full disk need root (tmpfs)"; fi

bench: $(STAMPS)/built
	$(VPY) -m pip install -q -r requirements/bench.txt -c requirements/constraints.txt
	$(VPY) benchmarks/run_all.py

# A wheel that runs without the -dev packages: built by scikit-build-core,
# repaired by auditwheel (every non-system shared library copied in, renamed),
# then installed into a fresh venv and run from outside the checkout.
WHEEL_DIR ?= dist
wheel: $(STAMPS)/pydeps
	$(VPY) -m pip install -q -r requirements/wheel.txt -c requirements/constraints.txt
	rm -rf build/wheel $(WHEEL_DIR)/qogi-*.whl
	$(VPY) -m pip wheel -q --no-build-isolation --no-deps -w build/wheel/raw . \
	  -Cbuild-dir=build/wheel/cmake
	PATH=$(abspath $(VENV))/bin:$$PATH $(VENV)/bin/auditwheel repair -w $(WHEEL_DIR) build/wheel/raw/qogi-*.whl
	$(VENV)/bin/auditwheel show $(WHEEL_DIR)/qogi-*.whl
	@ls -l $(WHEEL_DIR)/qogi-*.whl
	PYTHON=$(PYTHON) scripts/check_wheel.sh $(WHEEL_DIR)/qogi-*.whl

# The engine, its tests and the bindings built with clang, warnings as errors.
check-clang: $(STAMPS)/pydeps
	$(VENV)/bin/cmake -S . -B build/clang -G Ninja -DCMAKE_CXX_COMPILER=clang++ \
	  -DQOGI_WERROR=ON -DQOGI_BUILD_TESTS=ON -DQOGI_BUILD_PYTHON=ON \
	  -Dpybind11_DIR=$$($(VPY) -m pybind11 --cmakedir) -DPython_EXECUTABLE=$(abspath $(VPY))
	$(VENV)/bin/cmake --build build/clang
	$(VENV)/bin/ctest --test-dir build/clang --output-on-failure -j $(JOBS)

# `make gui` or `make gui REC=path/to/recording.h5`
gui: $(STAMPS)/built
	$(VENV)/bin/qogi gui $(REC)

clean:
	rm -rf build

distclean: clean
	rm -rf $(VENV)

FORCE:
