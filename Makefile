# Two commands do everything: `make run` and `make test`. Both create the Python environment
# (pinned gmsh and meshio from PyPI) and build in release mode first.

PYTHON ?= python3
VENV := .venv
VENV_STAMP := $(VENV)/.installed-gmsh-4.15.2-meshio-5.3.5
CARGO ?= cargo

.PHONY: run test venv build bench lint clean

run: venv build
	./target/release/hbcontact run pipelines/quickstart.yaml

# The fuzz targets (tests/fuzz.rs) run this many cases each; the long run is 100000.
PROPTEST_CASES ?= 256

test: venv build
	PROPTEST_CASES=$(PROPTEST_CASES) $(CARGO) test --release

venv: $(VENV_STAMP)

$(VENV_STAMP):
	$(PYTHON) -m venv $(VENV)
	$(VENV)/bin/pip install --quiet --disable-pip-version-check gmsh==4.15.2 meshio==5.3.5
	touch $@

build:
	$(CARGO) build --release

bench: venv build
	$(CARGO) bench --bench stages
	$(CARGO) bench --bench contact
	$(CARGO) bench --bench study
	$(CARGO) bench --bench sweep
	$(CARGO) bench --bench goals
	$(CARGO) bench --bench spline
	$(CARGO) bench --bench scenes

lint:
	$(CARGO) fmt --check
	$(CARGO) clippy --release --all-targets -- -D warnings

clean:
	rm -rf target $(VENV) output/*/ output/.mesh-cache
