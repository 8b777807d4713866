# Two commands do everything on a fresh machine: `make render` and `make test`.
PYTHON ?= python3.11
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
# Test processes (pytest-xdist).  Two on this 2-core machine: the fast tier took 8 min 35 s
# against 14 min 0 s in one process (same clean clone, one after the other); one process
# leaves a core idle while a test waits on Cycles, on a worker pool or on NumPy's single thread.
TEST_JOBS ?= 2

.PHONY: render test test-slow bench extension clean

$(STAMP): requirements.txt
	@command -v $(PYTHON) >/dev/null 2>&1 || { echo "error: $(PYTHON) not found (Blender 5.0's bpy needs Python 3.11); set PYTHON=..."; exit 1; }
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -r requirements.txt
	touch $(STAMP)

venv: $(STAMP)

render: $(STAMP)
	@mkdir -p out
	$(PY) render.py sample_blends/cornell_box.blend --output out/cornell_box.exr --png out/cornell_box.png

test: $(STAMP)
	$(PY) -m pytest -m "not slow" -q -n $(TEST_JOBS)

test-slow: $(STAMP)
	$(PY) -m pytest -m slow -q -n $(TEST_JOBS)

# Installable zips (one per platform, with embreex wheels) in dist/, built by Blender's own tool.
extension: $(STAMP)
	$(PY) tools/build_extension.py --output-dir dist

bench: $(STAMP)
	$(PY) benchmarks/throughput.py

clean:
	rm -rf $(VENV) out dist
