# Set-up is part of every target: a missing .venv is created and filled.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
SD     := $(VENV)/bin/shapedisplay
STAMP  := $(VENV)/.installed
OUT    := out

.PHONY: install test demo bench report clean

$(STAMP): pyproject.toml scripts/install-system-deps.sh
	sh scripts/install-system-deps.sh --with-xvfb
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q -e '.[all,test]'
	@touch $@

install: $(STAMP)

test: $(STAMP)
	$(PY) -m pytest -q -n 2 -p no:cacheprovider

demo: $(STAMP)
	@mkdir -p $(OUT)
	$(SD) compile assets/maps/tent_profile.png -o $(OUT)/tent.npz --size 60x4mm --height 0:2mm --mapping height --n-base 0.5N --n-gain 2N/mm
	$(SD) inspect $(OUT)/tent.npz

bench: $(STAMP)
	for b in benchmarks/bench_*.py; do echo "== $$b"; $(PY) $$b || exit 1; done

clean:
	rm -rf $(OUT) build *.egg-info
