# vidtrack: `make demo` tracks the bundled sample; `make test` runs the test suite.
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
OUT    ?= out
# The VOT toolkit (for the TraX test) lives in a venv of its own: it depends on opencv-python,
# which must never share an environment with vidtrack's opencv-contrib-python-headless.
VOT_VENV ?= .venv-vot
VOT_BIN  := $(VOT_VENV)/bin
# The got10k toolkit (the reference scores of OTB, UAV123 and GOT-10k) gets a venv of its own too:
# it is the benchmarks' Python toolkit, kept apart from vidtrack's dependencies.
GOT10K_VENV ?= .venv-got10k
GOT10K_BIN  := $(GOT10K_VENV)/bin
# Datumaro reads vidtrack's CVAT and MOT exports back in tests/test_exports.py: a venv of its own, since it
# depends on opencv-python-headless, which must never share one with vidtrack's OpenCV.
DATUMARO_VENV ?= .venv-datumaro
DATUMARO_BIN  := $(DATUMARO_VENV)/bin
# TrackEval (HOTA, IDF1, MOTA of several targets) too: it depends on opencv-python.
TRACKEVAL_VENV ?= .venv-trackeval
TRACKEVAL_BIN  := $(TRACKEVAL_VENV)/bin
# Every install takes the tested versions from these files (`make constraints` rewrites them).
CONSTRAINTS     ?= constraints.txt
VOT_CONSTRAINTS ?= constraints-vot.txt
GOT10K_CONSTRAINTS ?= constraints-got10k.txt
DATUMARO_CONSTRAINTS ?= constraints-datumaro.txt
TRACKEVAL_CONSTRAINTS ?= constraints-trackeval.txt

.PHONY: demo test lint install install-dev vot-env got10k-env datumaro-env trackeval-env constraints sample clean

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

# got10k 0.1.3 imports six without declaring it
$(GOT10K_VENV)/.installed: $(GOT10K_CONSTRAINTS)
	$(PYTHON) -m venv $(GOT10K_VENV)
	$(GOT10K_BIN)/python -m pip install --quiet --upgrade pip
	$(GOT10K_BIN)/python -m pip install --quiet -c $(GOT10K_CONSTRAINTS) got10k six
	touch $@

$(DATUMARO_VENV)/.installed: $(DATUMARO_CONSTRAINTS)
	$(PYTHON) -m venv $(DATUMARO_VENV)
	$(DATUMARO_BIN)/python -m pip install --quiet --upgrade pip
	$(DATUMARO_BIN)/python -m pip install --quiet -c $(DATUMARO_CONSTRAINTS) datumaro
	touch $@

$(TRACKEVAL_VENV)/.installed: $(TRACKEVAL_CONSTRAINTS)
	$(PYTHON) -m venv $(TRACKEVAL_VENV)
	$(TRACKEVAL_BIN)/python -m pip install --quiet --upgrade pip
	$(TRACKEVAL_BIN)/python -m pip install --quiet -c $(TRACKEVAL_CONSTRAINTS) trackeval
	touch $@

install: $(VENV)/.installed
install-dev: $(VENV)/.installed-dev
vot-env: $(VOT_VENV)/.installed
got10k-env: $(GOT10K_VENV)/.installed
datumaro-env: $(DATUMARO_VENV)/.installed
trackeval-env: $(TRACKEVAL_VENV)/.installed

# After adding or upgrading a dependency: install it, run `make test`, then `make constraints`.
constraints: $(BIN)/python
	@{ echo "# Tested versions of vidtrack's dependencies (make constraints writes this file from .venv)."; \
	   $(BIN)/python -m pip freeze --exclude-editable; } > $(CONSTRAINTS)
	@if [ -x $(VOT_BIN)/python ]; then { echo "# The VOT toolkit's own venv (make vot-env), tested with vidtrack trax."; \
	   $(VOT_BIN)/python -m pip freeze; } > $(VOT_CONSTRAINTS); fi
	@if [ -x $(GOT10K_BIN)/python ]; then { echo "# The got10k toolkit's own venv (make got10k-env), the reference of vidtrack eval's scores."; \
	   $(GOT10K_BIN)/python -m pip freeze; } > $(GOT10K_CONSTRAINTS); fi
	@if [ -x $(DATUMARO_BIN)/python ]; then { echo "# Datumaro's own venv (make datumaro-env): the independent reader of vidtrack's CVAT and MOT exports."; \
	   $(DATUMARO_BIN)/python -m pip freeze; } > $(DATUMARO_CONSTRAINTS); fi
	@if [ -x $(TRACKEVAL_BIN)/python ]; then { echo "# TrackEval's own venv (make trackeval-env), the scores of several targets."; \
	   $(TRACKEVAL_BIN)/python -m pip freeze; } > $(TRACKEVAL_CONSTRAINTS); fi
	@echo "constraints: wrote $(CONSTRAINTS)$$([ -x $(VOT_BIN)/python ] && echo " and $(VOT_CONSTRAINTS)")$$([ -x $(GOT10K_BIN)/python ] && echo " and $(GOT10K_CONSTRAINTS)")$$([ -x $(DATUMARO_BIN)/python ] && echo " and $(DATUMARO_CONSTRAINTS)")$$([ -x $(TRACKEVAL_BIN)/python ] && echo " and $(TRACKEVAL_CONSTRAINTS)")"

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

test: install-dev vot-env got10k-env datumaro-env trackeval-env lint
	VIDTRACK_VOT=$(abspath $(VOT_BIN))/vot VIDTRACK_GOT10K=$(abspath $(GOT10K_BIN))/python \
		VIDTRACK_DATUMARO=$(abspath $(DATUMARO_BIN))/python VIDTRACK_TRACKEVAL=$(abspath $(TRACKEVAL_BIN))/python \
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
	rm -rf $(VENV) $(VOT_VENV) $(GOT10K_VENV) $(DATUMARO_VENV) $(TRACKEVAL_VENV) $(OUT) .pytest_cache
