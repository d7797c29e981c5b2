PYTHON ?= python3
PIP ?= $(PYTHON) -m pip
# Where torch comes from. Empty: pip's default index, which on Linux x86-64 gives the CUDA
# build and its nvidia-* wheels. For the CPU-only build, set it to the CPU index URL that
# PyTorch's "Get started" page gives for pip: make install TORCH_INDEX=<that URL>
TORCH_INDEX ?=
# The browser the report's browser test drives (tests/report/test_report_browser.py).
CHROMIUM ?= chromium
# The exact versions of every distribution that decides a pixel (a pip constraints file,
# read at run time by robodepth verify and selftest too).
LOCK := robodepth_cli/constraints.txt

.PHONY: install test test-fast bench demo selftest-record

install:
	$(PIP) install $(if $(TORCH_INDEX),--index-url $(TORCH_INDEX) )-c $(LOCK) torch
	$(PIP) install -c $(LOCK) -e '.[test,dask,models,figures,exr,export,video]'
	# Frost textures only: the package's own dependencies (opencv-python, ...) are not wanted.
	$(PIP) install --no-deps -c $(LOCK) imagecorruptions-imaug
	# Every numba kernel compiled now, into the cache the install reads: no command waits for a
	# compile later (docs/development.md says what a read-only install and a Dask worker need).
	$(PYTHON) -m robodepth_cli.warmup
	# Headless Chromium for the browser test, where this system lets us install it (Debian
	# or Ubuntu, as root); anywhere else, say how: only that one test needs it.
	@if command -v $(CHROMIUM) >/dev/null 2>&1; then :; \
	elif command -v apt-get >/dev/null 2>&1 && [ "$$(id -u)" = 0 ]; then \
	  apt-get update && apt-get install -y chromium || echo "make install: apt-get could not install chromium; the browser test will fail until it is installed" >&2; \
	else \
	  echo "make install: the browser test needs Chromium (not found): install your system's chromium package (Debian/Ubuntu: sudo apt-get install -y chromium)" >&2; \
	fi

test:
	$(PYTHON) -m ruff check .
	$(PYTHON) -m pytest -q

# The inner loop: everything but the tests marked slow (long end-to-end runs).
test-fast:
	$(PYTHON) -m ruff check .
	$(PYTHON) -m pytest -q -m "not slow"

bench:
	$(PYTHON) -m bench.run

# Maintainers only: rewrite robodepth selftest's reference (robodepth_cli/selftest/data/
# reference.json and reference.xz) from this install, which must be the locked one. Run it
# after any change to pixels, to the selftest's builds or fixtures, or to the lock.
selftest-record:
	$(PYTHON) -m robodepth_cli.selftest --record

# The whole loop on the fixtures: the KITTI frames get synthetic velodyne scans (copied in
# from their own tree, so the tests' KITTI fixture stays without ground truth), the build
# writes gt_depths.npz beside the images, and sample predictions are evaluated and scored.
demo:
	@set -e; out=$$(mktemp -d -t robodepth-demo.XXXXXX); \
	fx=tests/data/fixtures; rd="$(PYTHON) -m robodepth_cli.cli"; \
	cp -R $$fx/kitti_raw $$out/kitti_raw; cp -R $$fx/kitti_velodyne/. $$out/kitti_raw/; \
	$$rd build kitti-c --root $$out/kitti_raw --split $$fx/kitti_split.txt --out $$out/kitti-c; \
	$$rd verify $$out/kitti-c; \
	$$rd gt kitti --root $$out/kitti_raw --split $$fx/kitti_split.txt --out $$out/gt_depths.npz; \
	$$rd evaluate $$out/kitti-c --pred tests/data/predictions/kitti-c --allow-partial --out $$out/results.csv; \
	$$rd score $$out/results.csv --benchmark kitti-c --allow-partial --plot $$out/ce.png; \
	$$rd build nyudepth2-c --root $$fx/nyu --split $$fx/nyu_split.txt --out $$out/nyudepth2-c; \
	$$rd verify $$out/nyudepth2-c; \
	$$rd gt nyu --root $$fx/nyu --split $$fx/nyu_split.txt --out $$out/nyu_test; \
	echo "demo output: $$out (e.g. $$out/kitti-c/zoom_blur/3/kitti_data/2011_09_26/2011_09_26_drive_0002_sync/image_02/data/0000000069.png, $$out/results.csv, $$out/ce.png; delete it when done)"
