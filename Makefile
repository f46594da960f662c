# rbsim: the README's set-up is `make demo` then `make test`.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
BUILD_DEPS := $(VENV)/.build-deps
ENGINE := CMakeLists.txt $(shell find cpp -name '*.cpp' -o -name '*.hpp')
SCENES := $(wildcard scenes/*.yaml)
OUTS   := $(patsubst scenes/%.yaml,out/%.h5,$(SCENES))
DEMO   := scenes/pyramid.yaml

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
# are used in place, the engine is rebuilt when a C++ file changes
$(STAMP): $(BUILD_DEPS) pyproject.toml $(ENGINE)
	$(BIN)/pip install --quiet --no-build-isolation -e '.[test,plot]'
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

demo: $(STAMP)
	@mkdir -p out
	$(BIN)/rbsim run $(DEMO) -o out/demo.h5
	$(BIN)/rbsim render out/demo.h5 -o out/demo.gif
	$(BIN)/rbsim render out/demo.h5 -o out/demo.html
	@echo "trajectory written to out/demo.h5 (inspect it with: $(BIN)/rbsim info out/demo.h5)"
	@echo "watch it: out/demo.gif, or open out/demo.html in a browser"

batch: $(OUTS)

out/%.h5: scenes/%.yaml $(STAMP) $(wildcard rbsim/*.py)
	@mkdir -p out
	$(BIN)/rbsim run $< -o $@ --quiet

COMPARE_SCENES := $(wildcard scenes/compare/*.yaml scenes/compare/statistics/*.yaml)

# rbsim against pymunk on every scene of scenes/compare/ (and its statistics/); fails if
# any exits non-zero.
.PHONY: compare
compare: $(STAMP)
	@status=0; for s in $(COMPARE_SCENES); do \
		$(BIN)/rbsim compare $$s -o out/compare || status=1; \
	done; exit $$status

bench: $(STAMP)
	$(BIN)/python -m bench

# The hard cases of scenes/hard/ in rbsim and pymunk: prints the table and rewrites the
# README's hard-case block (about 2 min; pymunk's base-100 pyramid is half of it).
.PHONY: hard
hard: $(STAMP)
	$(BIN)/python -m rbsim.hard --readme README.md

# Speed against error on scenes/reference/ and cost against bodies, both engines:
# regenerates reports/work-precision.md, its plots and reports/data/ (about 10 min).
.PHONY: report
report: $(STAMP)
	$(BIN)/python -m rbsim.report -o reports

clean:
	rm -rf out .pytest_cache build *.egg-info rbsim/__pycache__ tests/__pycache__ bench/__pycache__
