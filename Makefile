# vidtrack: `make demo` tracks the bundled sample; `make test` runs the test suite.
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
OUT    ?= out

.PHONY: demo test install install-dev sample clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

$(VENV)/.installed: $(BIN)/python pyproject.toml
	$(BIN)/python -m pip install --quiet -e .
	touch $@

$(VENV)/.installed-dev: $(BIN)/python pyproject.toml
	$(BIN)/python -m pip install --quiet -e ".[dev]"
	touch $(VENV)/.installed $@

install: $(VENV)/.installed
install-dev: $(VENV)/.installed-dev

demo: install
	@mkdir -p $(OUT)
	$(BIN)/vidtrack data/sample.mp4 --init-box $$(head -n 1 data/sample_groundtruth.txt) \
		--filter $${FILTER:-mil} -o $(OUT)/demo.mp4 --boxes $(OUT)/demo_boxes.txt --log $(OUT)/demo_log.csv
	@echo "demo: annotated video $(OUT)/demo.mp4, boxes $(OUT)/demo_boxes.txt, per-frame log $(OUT)/demo_log.csv"

test: install-dev
	$(BIN)/python -m pytest $(PYTEST_ARGS)

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
	rm -rf $(VENV) $(OUT) .pytest_cache
