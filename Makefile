# SMM control stack: every target sets itself up on a fresh machine (Python >= 3.11 and make are all it needs).
#   make demo   full closed-loop run on the simulator (the main job)
#   make test   the whole test suite on two workers (unit, bag, node, end-to-end in private network namespaces);
#               nothing in it needs the machine to keep up with a clock
#   make test-realtime  the tests that need the wall clock kept (1 kHz / 100 Hz runs): a quiet machine only
#   make test-other-cpu  the tests against data made on another machine, under other numeric paths
#   make bench  benchmarks: figures and ratios, never pass/fail on a shared machine's timing
#   make soak   the bench path for SOAK_MINUTES (10) under scripted faults, recorded (docs/SOAK.md)
#   make test-bags  the whole corpus of bags of other writers (make test runs a subset); UPSTREAM=DIR adds
#               every bag under DIR (rosbag2's test bags, MCAP conformance files: never committed)
# Re-running a target is quick: the virtual environment is rebuilt only when a requirements file or a
# package's setup.py/package.xml changes.

PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.smm-installed
PACKAGES := smm_schema smm_msgs_py smm_node_runtime smm_dynamics smm_controller smm_sim smm_hw_bridge smm_bench_emulator smm_bag smm_analysis smm_direct_loop smm_bringup smm_commissioning
PACKAGE_FILES := $(foreach p,$(PACKAGES),src/$(p)/setup.py src/$(p)/setup.cfg src/$(p)/package.xml) src/user_commands.py

# Keep DDS discovery on this machine unless the caller chose otherwise.
export ROS_AUTOMATIC_DISCOVERY_RANGE ?= LOCALHOST
export PYTHONDONTWRITEBYTECODE := 1

# The corpus's writer in another language: npm's @mcap/core (tests/bag/corpus/js), node and npm from apt if missing.
CORPUS_JS := tests/bag/corpus/js/.installed
$(CORPUS_JS): tests/bag/corpus/js/package.json tests/bag/corpus/js/package-lock.json
	@command -v npm >/dev/null 2>&1 || { apt-get update -qq && apt-get install -y -qq nodejs npm; }
	cd tests/bag/corpus/js && npm ci --no-audit --no-fund --silent
	@touch $@

.PHONY: soak setup test test-realtime test-bags corpus-table parameter-tables test-other-cpu demo bench lint typecheck reproduce sweep colcon clean mutation

setup: $(STAMP)

$(STAMP): requirements.txt requirements-dev.txt $(PACKAGE_FILES)
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --disable-pip-version-check -r requirements-dev.txt
	$(PY) -m pip install --quiet --disable-pip-version-check --no-deps --no-build-isolation \
		$(foreach p,$(PACKAGES),-e src/$(p))
	@touch $@

# Two pytest-xdist workers, each in a network namespace and a block of ROS_DOMAIN_IDs of its own (tests/conftest.py);
# loadgroup keeps each xdist_group's tests on one worker (docs/TESTING.md, "Two workers").
test: $(STAMP) $(CORPUS_JS)
	$(PY) -m pytest tests -n 2 --dist loadgroup

# The real-time versions of the hardware tests (marker realtime, deselected by pyproject's addopts): they need
# a quiet machine, as a bench run does (docs/TESTING.md, "Real-time tests").
test-realtime: $(STAMP)
	$(PY) -m pytest tests -m realtime

# Every corpus entry (docs/BAGS.md, "Bags of other writers"); make test-bags UPSTREAM=/path/to/bags
test-bags: $(STAMP) $(CORPUS_JS)
	SMM_BAG_CORPUS=full SMM_BAG_UPSTREAM="$(UPSTREAM)" $(PY) -m pytest tests/bag/test_corpus.py $(PYTEST_ARGS)

# Rewrites docs/BAGS.md's writer x command table from what the whole corpus gives.
corpus-table: $(STAMP) $(CORPUS_JS)
	$(PY) tests/bag/corpus/table.py

# Rewrites docs/NODES.md's parameter tables from the configs each node binds (smm_schema).
parameter-tables: $(STAMP)
	$(PY) tools/parameter_tables.py

# The cross_machine tests (data made on another machine) once per forced numeric path (OpenBLAS kernel,
# numpy SIMD, libm), after a table of the sample-bag rerun under each: see docs/TESTING.md.
test-other-cpu: $(STAMP)
	$(PY) tests/numeric_paths.py tests -m cross_machine -q

demo: $(STAMP)
	$(PY) -m smm_bringup.demo

bench: $(STAMP)
	$(PY) bench/run.py

# Mutation testing of the pure modules (mutmut 3, 25 min on a quiet 2-core machine; not part of `make test`). Report in
# out/mutation/report.md. Run some modules only: make mutation MUTATION_ARGS="--modules td fleso".
mutation: $(STAMP)
	$(PY) tools/mutation.py $(MUTATION_ARGS)

lint: $(STAMP)
	$(VENV)/bin/ruff check src tests bench tools

typecheck: $(STAMP)
	$(VENV)/bin/mypy

# A gain study on the batched closed loop: make sweep SPEC=examples/sweeps/case2_td_tradeoff.yaml [OUT=dir]
sweep: $(STAMP)
	$(VENV)/bin/smm-sweep $(SPEC) $(if $(OUT),--out $(OUT))

reproduce: $(STAMP)
	$(PY) -m smm_analysis.reproduction.cli --out out/reproduce

colcon: $(STAMP)
	$(VENV)/bin/colcon build --base-paths src --build-base build --install-base install

clean:
	rm -rf $(VENV) build install log out .pytest_cache .mypy_cache .ruff_cache .hypothesis

# The soak of the bench path (not in `make test`): the hardware graph in real time on the emulator, recorded,
# under scripted faults, in a private network namespace (docs/SOAK.md). make soak SOAK_MINUTES=60
# (SOAK_ARGS=--launch-arg=--force: arm past the preflight, whose refusal ends a soak)
SOAK_MINUTES ?= 10
SOAK_OUT ?= out/soak_$(shell date -u +%Y%m%d_%H%M%S)
SOAK_ARGS ?=
soak: $(STAMP)
	unshare --net -- $(PY) tests/netns_exec.py $(PY) tools/soak.py --minutes $(SOAK_MINUTES) --out $(SOAK_OUT) \
		$(SOAK_ARGS)
