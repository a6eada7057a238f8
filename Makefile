# Two commands do everything on a fresh machine: `make demo` (the main job) and `make test`.
VENV ?= .venv
PY := $(VENV)/bin/python
DEMO_OUT ?= demo_out

.PHONY: setup demo test docs bench clean

setup:
	EXTRAS=$(EXTRAS) bash scripts/setup.sh

demo: setup
	$(PY) -m orchestrate.demo --out $(DEMO_OUT)

test: setup
	$(PY) -m pytest -q -x --durations=15 tests

docs: setup
	$(PY) -m orchestrate.docs

clean:
	rm -rf $(DEMO_OUT) .pytest_cache
