# rbsim: the README's set-up is `make demo` then `make test`.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
BUILD_DEPS := $(VENV)/.build-deps
ENGINE := CMakeLists.txt $(shell find cpp -name '*.cpp' -o -name '*.hpp')
DEMO   := scenes/smash.yaml

.PHONY: install test lint demo batch bench clean cpp-test sanitize

install: $(STAMP)

# the venv and the engine's build tools (scikit-build-core, nanobind, cmake, ninja), so
# that a change to the engine rebuilds without fetching them again
$(BUILD_DEPS): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet 'scikit-build-core>=0.10' 'nanobind>=2.4' cmake ninja
	touch $(BUILD_DEPS)

# rbsim with its compiled engine (C++20 with the machine's g++), editable: Python files
# are used in place, the engine is rebuilt when a C++ file changes. Its modules are then
# compiled to bytecode once: pip does not for an editable install, and where Python may
# not write its caches (PYTHONDONTWRITEBYTECODE, a read-only tree) every process compiled
# them again, 0.1 s of each start (a file changed later is compiled again, as always)
$(STAMP): $(BUILD_DEPS) pyproject.toml $(ENGINE)
	$(BIN)/pip install --quiet --no-build-isolation -e '.[test,plot,mujoco]'
	$(BIN)/python -m compileall -q -j 0 rbsim > /dev/null
	touch $(STAMP)

lint: $(STAMP)
	$(BIN)/ruff check rbsim tests bench
	$(BIN)/ruff format --check rbsim tests bench

test: $(STAMP) lint cpp-test
	$(BIN)/pytest -q

# the engine's C++ unit tests (cpp/tests/test_*.cpp, one per source file), under ctest
cpp-test: $(BUILD_DEPS) $(ENGINE)
	$(BIN)/cmake -S . -B build/cpp-tests -G Ninja -DRBSIM_TESTS=ON -DCMAKE_MAKE_PROGRAM=$(CURDIR)/$(BIN)/ninja > /dev/null
	$(BIN)/cmake --build build/cpp-tests
	$(BIN)/ctest --test-dir build/cpp-tests --output-on-failure

# The engine under AddressSanitizer and UndefinedBehaviorSanitizer (plus libstdc++'s bounds
# assertions), then SANITIZE_TESTS against it; any sanitizer report fails the run. A separate
# non-editable build in build/sanitize/site (the editable install in .venv is left alone; its
# finder, set up by a .pth file, would win over PYTHONPATH, so python runs with -S: the venv's
# site-packages come on PYTHONPATH after the sanitized rbsim, their .pth files unprocessed).
# -P and --import-mode=append keep the source tree's rbsim (no _core) behind the built one.
# The interpreter is not built with ASan, so its runtime is preloaded; leaks are not checked
# (CPython leaks at exit). Tests of stages still placeholders fail on a partial port.
# RelWithDebInfo and no strip: nanobind strips Release modules, and reports need line numbers.
SANITIZE_TESTS ?= tests/test_contacts.py tests/test_contacts_output.py tests/test_hard.py \
	tests/test_solver_waves.py tests/test_solver_stages.py tests/test_shock_stage.py tests/test_narrowphase.py tests/test_broadphase.py \
	tests/test_trajectory3d.py tests/test_dynamics3d.py tests/test_continuous.py
SANITIZE_DIR   := build/sanitize
SANITIZE_ENV    = PYTHONPATH=$(SANITIZE_DIR)/site:$(VENV)/lib/python3.11/site-packages \
	LD_PRELOAD=$$(g++ -print-file-name=libasan.so):$$(g++ -print-file-name=libubsan.so) \
	ASAN_OPTIONS=detect_leaks=0:abort_on_error=1 UBSAN_OPTIONS=halt_on_error=1:print_stacktrace=1
sanitize: $(BUILD_DEPS)
	$(BIN)/python -m pip install --quiet --no-build-isolation --no-deps --upgrade \
		--target $(SANITIZE_DIR)/site -C build-dir=$(SANITIZE_DIR)/build -C install.strip=false -C cmake.build-type=RelWithDebInfo \
		-C cmake.define.RBSIM_SANITIZE=ON -C cmake.define.CMAKE_CXX_FLAGS=-D_GLIBCXX_ASSERTIONS .
	$(SANITIZE_ENV) $(BIN)/python -S -P -c "import rbsim._core as c, os, sys; \
		print('sanitized engine:', c.__file__); \
		so = open(c.__file__, 'rb').read(); \
		sys.exit(not (c.__file__.startswith(os.path.abspath('$(SANITIZE_DIR)/site')) \
		and b'__asan_report' in so and b'__ubsan_handle' in so))"
	$(SANITIZE_ENV) $(BIN)/python -S -P -m pytest -q -p no:cacheprovider --capture=sys --import-mode=append $(SANITIZE_TESTS)

demo: $(STAMP)
	@mkdir -p out
	$(BIN)/rbsim run $(DEMO) -o out/demo.h5
	$(BIN)/rbsim render out/demo.h5 -o out/demo.gif
	$(BIN)/rbsim render out/demo.h5 -o out/demo.html
	@echo "trajectory written to out/demo.h5 (inspect it with: $(BIN)/rbsim info out/demo.h5)"
	@echo "watch it: out/demo.gif, or open out/demo.html in a browser"

# every scene of scenes/ as one batch on a local Dask cluster (rbsim batch, see cli.md):
# out/<run-id>.h5 and out/summary.csv; runs already complete are skipped
batch: $(STAMP)
	$(BIN)/rbsim batch scenes/*.yaml -o out/

COMPARE_SCENES := $(wildcard scenes/compare/*.yaml scenes/compare/statistics/*.yaml \
	scenes/3d/compare/*.yaml scenes/3d/compare/statistics/*.yaml)

# rbsim against pymunk on every scene of scenes/compare/ (and its statistics/), and
# against MuJoCo on every scene of scenes/3d/compare/; fails if any exits non-zero.
.PHONY: compare
compare: $(STAMP)
	@status=0; for s in $(COMPARE_SCENES); do \
		$(BIN)/rbsim compare $$s -o out/compare || status=1; \
	done; exit $$status

# PyBullet, the third engine of the 3D table: the `bench` extra of pyproject.toml
# (a wheel, seconds), installed here rather than by `make install`
bench: $(STAMP)
	$(BIN)/python -m pip install -q "pybullet>=3.2"
	$(BIN)/python -m bench

# The hard cases of scenes/hard/ in rbsim and pymunk: prints the table and rewrites the
# README's hard-case block (about 2 min; pymunk's base-100 pyramid is half of it).
.PHONY: hard
hard: $(STAMP)
	$(BIN)/python -m rbsim.tools.hard --readme README.md

# Speed against error on scenes/reference/ and cost against bodies, both engines:
# regenerates reports/work-precision.md, its plots and reports/data/ (about 10 min).
.PHONY: report
report: $(STAMP)
	$(BIN)/python -m rbsim.tools.report -o reports

clean:
	rm -rf out .pytest_cache build *.egg-info tests/__pycache__ bench/__pycache__
	find rbsim -name __pycache__ -type d -prune -exec rm -rf {} +
