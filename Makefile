# Set-up is part of every target: a missing .venv is created and filled.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
SD     := $(VENV)/bin/shapedisplay
STAMP  := $(VENV)/.installed
OUT    := out

.PHONY: install test demo bench report generate docs docs-images fuzz clean

# the C engine and kernels are compiled by the install: a changed C source or setup.py installs again
ENGINE_SRC := setup.py $(wildcard shapedisplay/engine/sd_*.[ch] shapedisplay/render/sd_*.c shapedisplay/author/sd_kernels.c shapedisplay/_module.c)
$(STAMP): pyproject.toml scripts/install-system-deps.sh $(ENGINE_SRC)
	sh scripts/install-system-deps.sh --with-xvfb --with-studio --with-toolchains
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q -e '.[all,test,docs]'
	@touch $@

install: $(STAMP)

test: $(STAMP)
	$(PY) -m pytest -q -n 2 -p no:cacheprovider

demo: $(STAMP)
	@mkdir -p $(OUT)
	# 1. a height map -> friction-envelope table (the published tent profile)
	$(SD) compile assets/maps/tent_profile.png -o $(OUT)/tent.npz --size 60x4mm --height 0:2mm --mapping height --n-base 0.5N --n-gain 2N/mm
	$(SD) inspect $(OUT)/tent.npz
	# 2. the phone screen scene -> table, played by the exact stick-slip renderer
	$(SD) compile assets/scenes/phone.toml -o $(OUT)/phone.npz
	$(SD) play $(OUT)/phone.npz --stroke "62,2 -> 62,156 @ 30mm/s" --model exact --tick-rate 10kHz -o $(OUT)/phone.wav --trace-out $(OUT)/phone-trace.npz --plot $(OUT)/phone-trace.png
	# 3. a 3D model (keycap mesh) -> table, and a stroke across it
	$(SD) compile assets/meshes/keycap.stl -o $(OUT)/keycap.npz --resolution 0.1mm --up z
	$(SD) play $(OUT)/keycap.npz --stroke "0,9 -> 18,9 @ 20mm/s" -o $(OUT)/keycap.wav
	# 4. a 3D preview of the scene with the played stroke (off-screen)
	$(SD) preview $(OUT)/phone.npz --trace $(OUT)/phone-trace.npz --color N -o $(OUT)/phone-preview.png
	# 5. widgets that react (docs/reactive.md): press the button, flip the toggle, drag the slider's thumb across its detents
	$(SD) compile assets/scenes/reactive.toml -o $(OUT)/reactive.npz
	$(SD) play $(OUT)/reactive.npz --stroke "20,15 -> 20,20 @ 20mm/s; press 3N 150ms; -> 60,20 @ 20mm/s; press 3N 150ms; -> 15,45 @ 30mm/s; press 3N 50ms; -> 55,45 @ 20mm/s press 3N; press 0N 10ms" --model jump -o $(OUT)/reactive.wav --trace-out $(OUT)/reactive-trace.npz --plot $(OUT)/reactive-trace.png
	@echo "demo outputs in $(OUT)/: tent.npz phone.npz phone.wav phone-trace.npz phone-trace.png phone-preview.png keycap.npz keycap.wav reactive.npz reactive.wav reactive-trace.npz reactive-trace.png"

bench: $(STAMP)
	for b in benchmarks/bench_*.py; do echo "== $$b"; $(PY) $$b || exit 1; done

report: $(STAMP)
	@mkdir -p $(OUT)/report
	$(SD) report accuracy -o $(OUT)/report
	$(SD) report stability -o $(OUT)/report

# Files derived from the runtime's model registry and layouts (dispatch.py, engine/sd_layout.h,
# KERNEL_SOURCES_SHA256 lines): run after changing a kernel or adding a model; tests check they are current.
generate: $(STAMP)
	$(PY) -m shapedisplay.render.codegen

# The API reference from the docstrings (docs/api, Sphinx autodoc), warnings as errors, into $(OUT)/docs;
# tests/test_docs_build.py builds it the same way in make test.
docs: $(STAMP)
	$(PY) -m sphinx -W --keep-going -q -b html docs/api $(OUT)/docs
	@echo "API reference: $(OUT)/docs/index.html"

# Every picture in docs/images from the shipped samples, byte-stable (tests/test_docs_images.py compares them);
# previews need off-screen OpenGL, the studio screenshot Chromium (skipped with a note where missing). ~2 min.
docs-images: $(STAMP)
	$(PY) scripts/docs_images.py

# The C engine under libFuzzer, double and single builds side by side, FUZZ_SECONDS (60) each
# (shapedisplay/engine/README.md, Fuzzing; the seeds are exported with the installed CLI).
FUZZ_SECONDS ?= 60
fuzz: $(STAMP)
	$(MAKE) -C shapedisplay/engine -j2 fuzz FUZZ_SECONDS=$(FUZZ_SECONDS)

clean:
	rm -rf $(OUT) build *.egg-info
