# rotavat: `make run` (venv + install + the whole pipeline on sample_data/) and `make test`.
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed-stamp
OUT    ?= out
SAMPLE := sample_data

.PHONY: install run test test-slow bench bench-quick fuzz sample clean

$(STAMP): pyproject.toml
	@bash tools/system_deps.sh
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $(STAMP)

install: $(STAMP)

run: install
	@bash tools/pipeline.sh $(BIN)/rotavat $(SAMPLE) $(OUT)

# make test: everything but the real-process tests (pytest -m slow), on every core (pytest-xdist; a
# format's tests share one worker: --dist loadgroup);
# make test-slow: those alone, one at a time (they measure memory, processes and time). CI runs both.
test: install
	$(BIN)/python -m pytest -n auto --dist loadgroup -m "not slow"

test-slow: install
	$(BIN)/python -m pytest -m slow

bench: install
	$(BIN)/python benchmarks/run_all.py

bench-quick: install
	$(BIN)/python benchmarks/run_all.py --quick

# Randomized hostile-input campaign (tests/fuzz/run_fuzz.py: a few minutes; FUZZ_ARGS="--iterations N --seed S").
fuzz: install
	$(BIN)/python tests/fuzz/run_fuzz.py $(FUZZ_ARGS)

# Regenerate the committed sample scene (deterministic).
sample: install
	rm -rf $(SAMPLE)/scene
	$(BIN)/rotavat synth $(SAMPLE)/scene --seed 7 --frames 4 --people 5 --image-size 1280 720 --hps-focal cliff --quiet

clean:
	rm -rf $(VENV) $(OUT) .pytest_cache
