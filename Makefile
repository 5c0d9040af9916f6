# The two set-up commands of the README: `make demo` and `make test`.
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
PIP    := $(PY) -m pip
BIN    := $(VENV)/bin

.PHONY: demo test lint test-all sysdeps sysdeps-egl venv install install-test clean bench

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

$(VENV)/.created:
	$(PYTHON) -m venv $(VENV)
	$(PIP) install -q --upgrade pip
	touch $@

venv: $(VENV)/.created

$(VENV)/.installed: $(VENV)/.created pyproject.toml
	$(PIP) install -q -e .
	touch $@

$(VENV)/.installed-test: $(VENV)/.installed
	$(PIP) install -q -e '.[test,pyrender]'
	touch $@

install: sysdeps $(VENV)/.installed
install-test: sysdeps sysdeps-egl $(VENV)/.installed-test

demo: install
	$(BIN)/aerial-synth place --scenario jam --scene city_park --seed 0 --out out/demo
	@echo "demo output in out/demo/ (placement.json, placement.png)"

lint: install-test
	$(BIN)/ruff check aerial_synth tests tools

test: install-test
	$(BIN)/ruff check aerial_synth tests tools
	$(BIN)/python -m pytest -q

test-all: install-test
	$(BIN)/python -m pytest -q -m "slow or not slow"

# Benchmark suite (tools/bench_suite.py runs tools/bench_*.py and more): writes bench.json.
bench: install-test
	$(BIN)/python tools/bench_suite.py --out bench.json --export-presets full,fast

clean:
	rm -rf $(VENV) out .pytest_cache
