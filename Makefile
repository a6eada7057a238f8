# Two commands do everything on a fresh machine: `make demo` (the main job) and `make test`.
# `make test` leaves out the tests marked `slow` (pytest.mark.slow, pyproject.toml); `make test-slow` runs only
# those; `make lint` runs ruff (its rules in pyproject.toml); CI (.ci/run) runs the lint, then both.
VENV ?= .venv
PY := $(VENV)/bin/python
DEMO_OUT ?= demo_out

.PHONY: setup demo lint test test-slow docs bench clean

setup:
	EXTRAS=$(EXTRAS) bash scripts/setup.sh

demo: setup
	$(PY) -m orchestrate.demo --out $(DEMO_OUT) --overwrite

lint: setup
	$(PY) -m ruff check .

test: setup
	$(PY) -m pytest -q -x --durations=15 -m "not slow" tests

# pytest exits 5 when no test is selected: with no test marked slow there is nothing to fail.
test-slow: setup
	$(PY) -m pytest -q -x --durations=15 -m slow tests; status=$$?; \
	if [ $$status -eq 5 ]; then echo "test-slow: no test is marked slow"; exit 0; fi; exit $$status

docs: setup
	$(PY) -m orchestrate.docs

clean:
	rm -rf $(DEMO_OUT) .pytest_cache
