# The two commands a newcomer needs (see README): `make demo` and `make test`.
VENV   := .venv
STAMP  := $(VENV)/.installed
TEST_STAMP := $(VENV)/.installed-test
PIPE   := $(VENV)/bin/pipeline
PYTEST := $(VENV)/bin/python -m pytest

.PHONY: demo test test-all bench install clean

$(STAMP): pyproject.toml scripts/bootstrap.sh
	bash scripts/bootstrap.sh
	touch $(STAMP)

# Tests also need Debian's chromium (headless web-viewer test) and hdf5-tools (h5dump 1.10 reads a
# fresh dataset file); `make demo` does not.
$(TEST_STAMP): pyproject.toml scripts/bootstrap.sh
	EXTRA_PACKAGES="chromium hdf5-tools" bash scripts/bootstrap.sh
	touch $(STAMP) $(TEST_STAMP)

install: $(STAMP)

## Main job on the embedded default: build meshes from scans/, simulate, print where results are.
demo: $(STAMP)
	$(PIPE) run workflows/natural.yaml

## Test suite as CI runs it (slow tests excluded).
test: $(TEST_STAMP)
	$(PYTEST) -m "not slow" -q

## Everything, slow physics and cluster tests included.
test-all: $(TEST_STAMP)
	$(PYTEST) -q

bench: $(STAMP)
	for b in benchmarks/bench_*.py; do $(VENV)/bin/python $$b || exit 1; done

clean:
	rm -rf outputs .pytest_cache
