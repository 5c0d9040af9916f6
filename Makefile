# The two set-up commands of the README: `make demo` and `make test`. `make demo` also compiles
# the render kernels into numba's cache (once per machine; the first export is then fast).
# What they install comes from the committed PEP 751 locks (pylock.toml, pylock.test.toml),
# read by uv (itself pinned, with hashes, in requirements/uv.txt); `make lock` regenerates them.
PYTHON ?= $(shell command -v python3.11 2>/dev/null || echo python3)
VENV   ?= .venv
PY     := $(VENV)/bin/python
PIP    := $(PY) -m pip
BIN    := $(VENV)/bin
UV     := $(BIN)/uv
# The locks hold Linux x86-64 wheels for CPython 3.11 on glibc >= 2.35 (Debian 12, Ubuntu 22.04
# and newer): open3d 0.19+ ships manylinux_2_35 wheels only (with 2_28 the lock fell back to
# open3d 0.18, which warns once per process that it has no CUDA device).
LOCK_PLATFORM := x86_64-manylinux_2_35
# `make lock` takes the newest versions published before this moment (so a rerun gives the
# same lock); `make lock LOCK_DATE=...` moves it on. Review the diff, then `make test`.
LOCK_DATE ?= 2026-11-27T00:00:00Z
LOCK_ARGS := --upgrade --python-version 3.11 --python-platform $(LOCK_PLATFORM) --generate-hashes \
	--format pylock.toml --exclude-newer $(LOCK_DATE) --quiet

.PHONY: pycheck demo test test-exact lint test-all test-latest test-train test-hostile lock dist sysdeps sysdeps-egl venv install install-test clean bench

# open3d's Linux wheel links against libusb-1.0; pip cannot provide it.
sysdeps:
	@if ldconfig -p 2>/dev/null | grep -q 'libusb-1.0.so.0'; then :; \
	elif [ "$$(id -u)" = "0" ] && command -v apt-get >/dev/null 2>&1; then \
	  echo "installing libusb-1.0-0 (needed by open3d) with apt-get"; \
	  DEBIAN_FRONTEND=noninteractive apt-get install -y -q libusb-1.0-0 >/dev/null 2>&1 || \
	  { apt-get update -q >/dev/null 2>&1 && DEBIAN_FRONTEND=noninteractive apt-get install -y -q libusb-1.0-0 >/dev/null; }; \
	else \
	  echo "aerial-synth needs the system library libusb-1.0-0 (open3d links against it)."; \
	  echo "Install it with:  sudo apt-get install libusb-1.0-0   and run make again."; \
	  exit 1; \
	fi

# Optional: Mesa's EGL (software, no GPU needed) for the pyrender backend and its test.
# Installed when running as root with apt; otherwise that one test is skipped, saying why.
sysdeps-egl:
	@if ldconfig -p 2>/dev/null | grep -q 'libEGL_mesa.so.0'; then :; \
	elif [ "$$(id -u)" = "0" ] && command -v apt-get >/dev/null 2>&1; then \
	  echo "installing Mesa EGL (libegl1 libegl-mesa0 libgl1-mesa-dri) for the pyrender backend"; \
	  DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends libegl1 libegl-mesa0 libgl1-mesa-dri >/dev/null 2>&1 || \
	  { apt-get update -q >/dev/null 2>&1 && DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends libegl1 libegl-mesa0 libgl1-mesa-dri >/dev/null 2>&1; } || \
	  echo "note: could not install Mesa EGL; the pyrender backend test will be skipped"; \
	else \
	  echo "note: no Mesa EGL (sudo apt-get install libegl1 libegl-mesa0 libgl1-mesa-dri); the pyrender backend test will be skipped"; \
	fi

# The locks are for CPython 3.11: say so in one line instead of failing inside the installer.
pycheck:
	@$(PYTHON) -c 'import sys; sys.exit(0 if sys.version_info[:2] == (3, 11) else 1)' 2>/dev/null || \
	{ echo "aerial-synth's locks (pylock.toml) are for Python 3.11; '$(PYTHON)' is $$($(PYTHON) -V 2>&1)."; \
	  echo "Install python3.11 (with venv) or run: make PYTHON=/path/to/python3.11"; exit 1; }

$(VENV)/.created: | pycheck
	$(PYTHON) -m venv $(VENV)
	$(PIP) install -q --disable-pip-version-check --require-hashes --no-deps -r requirements/uv.txt
	touch $@

venv: $(VENV)/.created

# Runtime from pylock.toml, the package itself editable, built by the locked setuptools.
$(VENV)/.installed: $(VENV)/.created pylock.toml pyproject.toml
	$(UV) pip install -q --python $(PY) -r pylock.toml
	$(UV) pip install -q --python $(PY) --no-deps --no-build-isolation -e .
	touch $@

# Runtime + test + pyrender + gpu extras from pylock.test.toml (the same versions as
# pylock.toml). The gpu extra (warp-lang, ~150 MB wheel) is in the test lock so that make test
# runs the warp-vs-raycast agreement tests on the CPU (tests/render/test_warp_backend.py).
$(VENV)/.installed-test: $(VENV)/.installed pylock.test.toml
	$(UV) pip install -q --python $(PY) -r pylock.test.toml
	touch $@

# Regenerate both locks from pyproject.toml's ranges (newest before LOCK_DATE). The runtime
# lock is constrained by the test lock, so the two never disagree on a version.
lock: $(VENV)/.created
	$(UV) pip compile pyproject.toml --extra test --extra pyrender --extra gpu requirements/build.in \
	  $(LOCK_ARGS) -o pylock.test.toml
	$(UV) pip compile pyproject.toml --extra test --extra pyrender --extra gpu requirements/build.in \
	  --python-version 3.11 --python-platform $(LOCK_PLATFORM) --exclude-newer $(LOCK_DATE) \
	  --upgrade --quiet --no-header --no-annotate -o $(VENV)/lock-constraints.txt
	$(UV) pip compile pyproject.toml requirements/build.in -c $(VENV)/lock-constraints.txt \
	  $(LOCK_ARGS) -o pylock.toml
	@echo "pylock.toml and pylock.test.toml regenerated (newest before $(LOCK_DATE)); review git diff, then make test"

# Drift check: the newest versions pyproject.toml allows, in a separate venv, no lock.
# Tests marked lock_exact (one machine's exact scene hashes) or lock_pinned (the scenes'
# tolerant fingerprints) hold only under the lock: their result is printed as information. Everything
# else must hold on any allowed version; its status is this target's status.
LATEST := .venv-latest
test-latest: sysdeps | pycheck
	rm -rf $(LATEST)
	$(PYTHON) -m venv $(LATEST)
	$(LATEST)/bin/python -m pip install -q --disable-pip-version-check --require-hashes --no-deps -r requirements/uv.txt
	$(LATEST)/bin/uv pip install -q --python $(LATEST)/bin/python --resolution highest --upgrade -e '.[test,pyrender,gpu]'
	@$(LATEST)/bin/uv pip freeze --python $(LATEST)/bin/python | grep -iE '^(numpy|scipy|shapely|open3d|trimesh|opencv-python-headless|numba|pyproj|osmium)==' | tr '\n' ' '; echo
	@echo "== lock_exact and lock_pinned tests (information: they hold only under the lock) =="
	-$(LATEST)/bin/python -m pytest -q -p no:cacheprovider -m '(lock_exact or lock_pinned) and not slow' --no-header -rf 2>&1 | tail -n 15
	@echo "== every other test (must hold on any allowed version) =="
	$(LATEST)/bin/python -m pytest -q -p no:cacheprovider -m 'not lock_exact and not lock_pinned and not slow'

# sim2real's CPU smoke test (tests/sim2real, marker `train`) in a separate environment with the
# [train] extra; `make test` stays torch-free. Everything but the training stack comes from
# the test lock (uv); torch/torchvision come from pip, which on this kind of machine takes
# them from local wheels (uv would download gigabytes); Ultralytics is pinned exactly and
# installed without its dependency list: all but two are in the lock already, and those two
# are left out on purpose (opencv-python would shadow the project's opencv-python-headless;
# polars only reads results.csv, which sim2real reads with the standard library).
TRAIN_VENV := .venv-train
TRAIN_PINS := torch==2.14.1 torchvision==0.29.1
ULTRALYTICS_PINS := ultralytics==8.4.190 ultralytics-thop==2.2.3
# Ultralytics imports matplotlib; the project does not (its charts are drawn with OpenCV), and
# the lock's open3d 0.20 no longer brings it: pinned here, with its own dependencies.
TRAIN_EXTRA_PINS := matplotlib==3.11.2
$(TRAIN_VENV)/.installed: pylock.test.toml pyproject.toml requirements/uv.txt | pycheck
	rm -rf $(TRAIN_VENV)
	$(PYTHON) -m venv $(TRAIN_VENV)
	$(TRAIN_VENV)/bin/python -m pip install -q --disable-pip-version-check --require-hashes --no-deps -r requirements/uv.txt
	$(TRAIN_VENV)/bin/uv pip install -q --python $(TRAIN_VENV)/bin/python -r pylock.test.toml
	$(TRAIN_VENV)/bin/uv pip install -q --python $(TRAIN_VENV)/bin/python --no-deps --no-build-isolation -e .
	$(TRAIN_VENV)/bin/python -m pip install -q --disable-pip-version-check $(TRAIN_PINS) $(TRAIN_EXTRA_PINS)
	$(TRAIN_VENV)/bin/python -m pip install -q --disable-pip-version-check --no-deps $(ULTRALYTICS_PINS)
	touch $@

test-train: sysdeps $(TRAIN_VENV)/.installed
	$(TRAIN_VENV)/bin/python -m pytest -q -p no:cacheprovider -m train tests/sim2real tests/stream

# The hostile-input fuzzer of the whole CLI (tools/hostile_fuzz.py, issue 37): 2,000 cases
# from every subcommand's argparse definition, each in a child process under a 4 GB
# address-space limit and a time limit. Prints the cases, failures and run time (a sample of
# 40 runs in make test).
HOSTILE_CASES ?= 2000
test-hostile: install-test
	nice $(BIN)/python tools/hostile_fuzz.py --cases $(HOSTILE_CASES) --jobs 2

install: sysdeps $(VENV)/.installed
install-test: sysdeps sysdeps-egl $(VENV)/.installed-test

demo: install
	$(BIN)/python -c 'from aerial_synth.render import frame, warm; warm.ensure_compiled(frame.render_frame)'
	$(BIN)/aerial-synth place --scenario jam --scene city_park --seed 0 --out out/demo
	@echo "demo output in out/demo/ (placement.json, placement.png)"

lint: install-test
	$(BIN)/ruff check aerial_synth tests tools

test: install-test
	$(BIN)/ruff check aerial_synth tests tools
	$(BIN)/python -m pytest -q

test-all: install-test
	$(BIN)/python -m pytest -q -m "(slow or not slow) and not lock_exact"

# Exact pins (marker lock_exact): scene hashes of the pinning machine's bits under the lock.
# Machine-specific: another CPU may round a last bit differently (docs/portability.md); make
# test checks the cross-machine fingerprints instead.
test-exact: install-test
	@echo "test-exact: machine-specific exact pins (lock_exact); they hold on the machine that pinned them"
	$(BIN)/python -m pytest -q -m "lock_exact"

# sdist and wheel in dist/ (python -m build, with the locked setuptools: no download).
dist: install-test
	rm -rf dist
	$(PY) -m build --no-isolation --outdir dist .

# Benchmark suite (tools/bench_suite.py runs tools/bench_*.py and more): writes bench.json.
bench: install-test
	$(BIN)/python tools/bench_suite.py --out bench.json --export-presets full,fast

clean:
	rm -rf $(VENV) $(LATEST) $(TRAIN_VENV) out .pytest_cache build dist *.egg-info
