# vidtrack: `make demo` tracks the bundled sample; `make test` runs the test suite.
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
OUT    ?= out
# The VOT toolkit (for the TraX test) lives in a venv of its own: it depends on opencv-python,
# which must never share an environment with vidtrack's opencv-contrib-python-headless.
VOT_VENV ?= .venv-vot
VOT_BIN  := $(VOT_VENV)/bin
# Every install takes the tested versions from these files (`make constraints` rewrites them).
CONSTRAINTS     ?= constraints.txt
VOT_CONSTRAINTS ?= constraints-vot.txt

.PHONY: demo test lint install install-dev vot-env constraints sample clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

$(VENV)/.installed: $(BIN)/python pyproject.toml $(CONSTRAINTS)
	$(BIN)/python -m pip install --quiet -c $(CONSTRAINTS) -e .
	touch $@

$(VENV)/.installed-dev: $(BIN)/python pyproject.toml $(CONSTRAINTS)
	$(BIN)/python -m pip install --quiet -c $(CONSTRAINTS) -e ".[dev]"
	touch $(VENV)/.installed $@

$(VOT_VENV)/.installed: $(VOT_CONSTRAINTS)
	$(PYTHON) -m venv $(VOT_VENV)
	$(VOT_BIN)/python -m pip install --quiet --upgrade pip
	$(VOT_BIN)/python -m pip install --quiet -c $(VOT_CONSTRAINTS) vot-toolkit attributee
	touch $@

install: $(VENV)/.installed
install-dev: $(VENV)/.installed-dev
vot-env: $(VOT_VENV)/.installed

# After adding or upgrading a dependency: install it, run `make test`, then `make constraints`.
constraints: $(BIN)/python
	@{ echo "# Tested versions of vidtrack's dependencies (make constraints writes this file from .venv)."; \
	   $(BIN)/python -m pip freeze --exclude-editable; } > $(CONSTRAINTS)
	@if [ -x $(VOT_BIN)/python ]; then { echo "# The VOT toolkit's own venv (make vot-env), tested with vidtrack trax."; \
	   $(VOT_BIN)/python -m pip freeze; } > $(VOT_CONSTRAINTS); fi
	@echo "constraints: wrote $(CONSTRAINTS)$$([ -x $(VOT_BIN)/python ] && echo " and $(VOT_CONSTRAINTS)")"

demo: install
	@mkdir -p $(OUT)
	$(BIN)/vidtrack data/sample.mp4 --init-box $$(head -n 1 data/sample_groundtruth.txt) \
		--filter $${FILTER:-mil} -o $(OUT)/demo.mp4 --boxes $(OUT)/demo_boxes.txt --log $(OUT)/demo_log.csv
	@echo "demo: annotated video $(OUT)/demo.mp4, boxes $(OUT)/demo_boxes.txt, per-frame log $(OUT)/demo_log.csv"

# The lint gate, run before the tests: ruff's rules and import-linter's layer contracts (both in
# pyproject.toml), so a lint error or an upward import fails `make test` and CI.
lint: install-dev
	$(BIN)/ruff check vidtrack tests scripts
	$(BIN)/lint-imports

test: install-dev vot-env lint
	VIDTRACK_VOT=$(abspath $(VOT_BIN))/vot $(BIN)/python -m pytest $(PYTEST_ARGS)

sample: install
	$(BIN)/python scripts/make_sample.py --out data

# headless Chromium (Debian's chromium) renders OUT/report.html in tests/test_eval_report.py: `make test`
# installs it once when missing and we are root, else that test skips its rendering check
.PHONY: browser
test: browser
browser:
	@command -v chromium >/dev/null 2>&1 || command -v chromium-browser >/dev/null 2>&1 || \
	  if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then \
	    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null; \
	  else echo "make: no chromium and not root: the report-rendering test will skip its browser check"; fi

clean:
	rm -rf $(VENV) $(VOT_VENV) $(OUT) .pytest_cache
