PYTHON ?= python3
PIP ?= $(PYTHON) -m pip

.PHONY: install test bench demo

install:
	$(PIP) install torch==2.13.0
	$(PIP) install -e '.[test]'
	# Frost textures only: the package's own dependencies (opencv-python, ...) are not wanted.
	$(PIP) install --no-deps imagecorruptions-imaug==1.1.5

test:
	$(PYTHON) -m pytest -q

bench:
	$(PYTHON) bench/run.py

demo:
	$(PYTHON) bench/demo.py
