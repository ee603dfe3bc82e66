# make test | make bench | make report | make microbench — each sets itself up on a clean
# Debian 12 machine (as root): Debian packages, then .venv with the project and dev extras.
SHELL := /bin/bash
VENV := .venv
PY := $(VENV)/bin/python
STAMPS := .make
DEBS := python3-venv git libosmesa6 libegl1 libegl-mesa0 libgl1-mesa-dri libllvm19 chromium \
	chromium-driver
OUT ?= results/bench
EXPERIMENT ?= experiments/default.yaml
export PYOPENGL_PLATFORM ?= osmesa

.PHONY: setup plugin test bench report motion scale alpha tune compare microbench microbench-compare reproduce lint clean

setup: $(STAMPS)/venv

$(STAMPS)/debs:
	@mkdir -p $(STAMPS)
	@missing=$$(for p in $(DEBS); do dpkg-query -W -f='$${Status}\n' $$p 2>/dev/null | grep -q 'install ok installed' || echo $$p; done); \
	if [ -n "$$missing" ]; then \
	  echo "installing Debian packages:" $$missing; \
	  if [ "$$(id -u)" = 0 ]; then SUDO=; else SUDO=sudo; fi; \
	  $$SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -qq --no-install-recommends $$missing >/dev/null; \
	fi
	@touch $@

# The distribution is hard-shadow-bench (`shadowbench` on PyPI is another project). A .venv made
# before the project took that name holds it as `shadowbench`: uninstalled first (only when its
# entry points are this project's techniques, with the egg-info its editable install left in the
# checkout), or every technique would be registered twice.
# Distributions the real corpus reads files from and never imports (scenes.yaml's package:
# meshes), pinned so that the files and the scenes' references stay; without their dependencies
# (robosuite's would bring numba and OpenCV for one STL).
CORPUS_FILES_ONLY = robosuite==1.5.2

# The project and its dev extras go in with uv, their bytecode compiled as pip does (without
# it, where PYTHONDONTWRITEBYTECODE is set, every process the tests start compiles pandas and
# scipy again); pip where uv cannot (no network to its downloads, an old platform), with the
# same pins from pyproject.toml. Measured in docs/benchmarks.md ("make test").
$(STAMPS)/venv: $(STAMPS)/debs pyproject.toml Makefile
	@test -x $(PY) || python3 -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip uv
	@if $(PY) -c "import importlib.metadata as m, sys; \
	  sys.exit(not any(e.value.startswith('techniques.') for e in \
	  m.distribution('shadowbench').entry_points.select(group='shadowbench.techniques')))" \
	  2>/dev/null; then $(PY) -m pip uninstall -q -y shadowbench; rm -rf shadowbench.egg-info; fi
	$(VENV)/bin/uv pip install -q --compile-bytecode --python $(PY) -e '.[dev]' \
	  || $(PY) -m pip install -q -e '.[dev]'
	$(VENV)/bin/uv pip install -q --compile-bytecode --python $(PY) --no-deps \
	  $(CORPUS_FILES_ONLY) || $(PY) -m pip install -q --no-deps $(CORPUS_FILES_ONLY)
	@touch $@

# A technique of your own (a folder with its pyproject.toml, e.g. a copy of examples/plugin)
# installed into .venv in editable mode: make plugin PLUGIN=path/to/it
plugin: setup
	@test -n "$(PLUGIN)" || { echo "usage: make plugin PLUGIN=path/to/your/plugin"; exit 2; }
	$(PY) -m pip install -q -e $(PLUGIN)
	$(VENV)/bin/shadowbench list | grep -i -A1 "plugin:" || true

# benchmarks run once each as plain tests here (their timings are make microbench's job)
# Two worker processes, a test module's tests in one of them (its module fixtures built once):
# most tests run one core at a time (Python, pandas, one GL pass), so the two cores halve it.
TEST_WORKERS ?= 2
test: setup
	$(VENV)/bin/lint-imports
	$(PY) -m pytest -q --benchmark-disable -n $(TEST_WORKERS) --dist loadfile

# Some failed runs (exit 1) still get their dashboard, which shows why; bad input (2) does not.
bench: setup
	@$(VENV)/bin/shadowbench run $(EXPERIMENT) --out $(OUT); status=$$?; \
	if [ $$status -le 1 ]; then $(VENV)/bin/shadowbench report $(OUT) || exit $$?; fi; \
	exit $$status

report: setup
	$(VENV)/bin/shadowbench report $(OUT)

# Shadows in motion (experiments/motion.yaml): every technique along camera and light orbits,
# scored per frame (flicker, worst frame) -> $(MOTION_OUT)/index.html, with its wall time.
MOTION_OUT ?= results/motion

# $(call timed_run,EXPERIMENT,OUT,TARGET): run it into OUT, build its dashboard, print the wall time
define timed_run
	@start=$$(date +%s); \
	$(VENV)/bin/shadowbench run $(1) --out $(2); status=$$?; \
	if [ $$status -le 1 ]; then $(VENV)/bin/shadowbench report $(2) || exit $$?; fi; \
	echo "make $(3): $$(( $$(date +%s) - start )) s wall time"; \
	exit $$status
endef

motion: setup
	$(call timed_run,experiments/motion.yaml,$(MOTION_OUT),motion)

# Production scale (experiments/scale.yaml): every technique at its defaults and two points of
# its quality curve on the four scene families at 10^3 .. 10^6 triangles -> $(SCALE_OUT).
SCALE_OUT ?= results/scale

scale: setup
	$(call timed_run,experiments/scale.yaml,$(SCALE_OUT),scale)

# Alpha-tested casters (experiments/alpha.yaml, issue 48): every technique at its defaults on
# cards (10^5, 10^6) and alpha_fence, with their cut-outs and with the same triangles opaque
# -> $(ALPHA_OUT), then the table (benchmarks/alpha_table.py; docs/benchmarks.md).
ALPHA_OUT ?= results/alpha

alpha: setup
	$(call timed_run,experiments/alpha.yaml,$(ALPHA_OUT),alpha)
	$(PY) benchmarks/alpha_table.py $(ALPHA_OUT)/results.csv

# Settings tuned per scene (docs/fairness.md): each technique's tunable settings searched
# against the reference on $(TUNE_FLAGS)' scenes, point by point of its quality curve ->
# $(TUNE_OUT)/tuned.yaml and its dashboard (the verdict on the tuned settings). Cached: the
# runs already in the folder are not rendered again, so a second make tune takes seconds.
# make tune OUT=dir as make bench; TUNE_FLAGS="--scenes a,b --techniques t1,t2 --budget N".
TUNE_OUT ?= $(if $(filter command line,$(origin OUT)),$(OUT),results/tune)
TUNE_FLAGS ?= --scenes real_airplane,real_plates

tune: setup
	@start=$$(date +%s); \
	$(VENV)/bin/shadowbench tune $(TUNE_FLAGS) --out $(TUNE_OUT); status=$$?; \
	if [ $$status -le 1 ]; then $(VENV)/bin/shadowbench report $(TUNE_OUT) || exit $$?; fi; \
	echo "make tune: $$(( $$(date +%s) - start )) s wall time"; \
	exit $$status

# Timings saved as JSON under .benchmarks/<machine>/; compare checks a new run against the last
# saved one without replacing it.
BENCH_FLAGS := -q tests/microbench --benchmark-only -p no:randomly \
	--benchmark-columns=min,median,max,stddev,rounds --benchmark-sort=name

microbench: setup
	$(PY) -m pytest $(BENCH_FLAGS) --benchmark-autosave

microbench-compare: setup
	$(PY) -m pytest $(BENCH_FLAGS) --benchmark-compare

# Every paper experiment (experiments/papers/*.yaml) into $(PAPERS_OUT)/<experiment>, then the
# claims (papers.json), each experiment's dashboard and the Papers page. About a minute on
# 2 cores with a warm reference cache (first run: add the references' ray tracing).
PAPERS_OUT ?= results/papers
PAPER_EXPERIMENTS := $(filter-out experiments/papers/scenes.yaml,$(wildcard experiments/papers/*.yaml))

reproduce: setup
	@start=$$(date +%s); \
	for experiment in $(PAPER_EXPERIMENTS); do \
	  $(VENV)/bin/shadowbench run $$experiment --out $(PAPERS_OUT)/$$(basename $$experiment .yaml) --quiet; \
	  status=$$?; [ $$status -le 1 ] || exit $$status; \
	done; \
	$(PY) -m papers $(PAPERS_OUT) || exit $$?; \
	echo "make reproduce: $$(( $$(date +%s) - start )) s wall time"

lint: setup
	$(VENV)/bin/ruff check harness techniques tests
	$(VENV)/bin/lint-imports

clean:
	rm -rf $(VENV) $(STAMPS) .pytest_cache

# What changed from one results folder to another (exit 1 when something got worse):
# make compare A=results/before B=results/after [COMPARE_FLAGS="--factor 1.2 --html diff.html"]
compare: setup
	@test -n "$(A)" -a -n "$(B)" || { echo "usage: make compare A=DIR B=DIR"; exit 2; }
	$(VENV)/bin/shadowbench compare $(A) $(B) $(COMPARE_FLAGS)
