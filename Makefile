# Octopaint: the two commands of the README.
#   make demo   set up, replay the scene trace, validate its tree dumps
#   make test   set up, run every test
# Setup is a virtual environment in .venv with the reference package
# (reference/pyproject.toml) installed in editable mode.

VENV := .venv
PY := $(VENV)/bin/python
OUT := out

.PHONY: demo test setup clean

setup: $(VENV)/.installed

$(VENV)/.installed: reference/pyproject.toml
	@python3 -m venv $(VENV) 2>/dev/null || { \
	  echo "python3 -m venv failed: installing python3-venv"; \
	  apt-get update -qq && apt-get install -y -qq python3-venv && python3 -m venv $(VENV); }
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e ./reference
	@touch $@

demo: setup
	$(VENV)/bin/octopaint-ref replay traces/scene.jsonl --out $(OUT)
	$(VENV)/bin/octopaint-ref check $(OUT)/*.npz

test: setup
	cd reference && ../$(PY) -m pytest -q -p no:cacheprovider tests

clean:
	rm -rf $(VENV) $(OUT)
