# scanamp: every step of the set-up lives here; a fresh machine needs only `make demo` or `make test`.
PY_SYS   ?= python3
VENV     := .venv
PY       := $(VENV)/bin/python
STAMP    := $(VENV)/.installed
SYSLIBS  := libusb-1.0-0 libgl1 libegl1 libgomp1
DEMO_OUT ?= demo-out
REAL     := .cache/real

.PHONY: setup syslibs warm demo test bench lint notebooks clean real-data

setup: $(STAMP)

syslibs:
	@missing=""; for p in $(SYSLIBS); do \
	  dpkg-query -W -f='$${Status}' $$p 2>/dev/null | grep -q "install ok installed" || missing="$$missing $$p"; \
	done; \
	if [ -n "$$missing" ]; then \
	  if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null; then \
	    echo "installing system libraries for open3d/VTK:$$missing"; \
	    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $$missing >/dev/null; \
	  else \
	    echo "error: open3d and VTK need the system libraries:$$missing (install them with: sudo apt-get install$$missing)"; exit 1; \
	  fi; \
	fi

$(STAMP): pyproject.toml
	@$(MAKE) --no-print-directory syslibs
	@test -x $(PY) || $(PY_SYS) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e ".[dev]"
	@$(MAKE) --no-print-directory warm
	@touch $(STAMP)

# Build the compiled kernels' cache (numba, cache=True) once, at set-up, by running the
# demo at its smallest scale: the first `make demo` is then as fast as the second.
warm:
	@echo "building the compiled kernels' cache (about 1.5 min, once)"
	@rm -rf .cache/warm
	$(PY) -m scanamp -q demo --scale test --out .cache/warm/demo
	@rm -rf .cache/warm

demo: $(STAMP)
	$(VENV)/bin/scanamp demo --out $(DEMO_OUT) --overwrite

test: $(STAMP)
	$(PY) -m pytest -q -n 2 --dist loadfile

bench: $(STAMP) real-data
	$(PY) benchmarks/run_all.py

# Real photographs for benchmarks/bench_real.py: the stereo chessboard pairs and the
# Middlebury Aloe pair (with its ground-truth disparity) that OpenCV ships as sample data,
# taken from Debian's opencv-doc package (downloaded and unpacked, not installed).
real-data: $(REAL)/opencv/.done

$(REAL)/opencv/.done:
	@command -v apt-get >/dev/null || { echo "error: real-data needs apt-get (Debian's opencv-doc package)"; exit 1; }
	@rm -rf $(REAL)/deb && mkdir -p $(REAL)/deb $(REAL)/opencv
	cd $(REAL)/deb && { apt-get download -qq opencv-doc 2>/dev/null || { apt-get update -qq && apt-get download -qq opencv-doc; }; }
	cd $(REAL)/deb && dpkg-deb -x opencv-doc_*.deb x
	cp $(REAL)/deb/x/usr/share/doc/opencv-doc/examples/data/left[01]*.jpg \
	   $(REAL)/deb/x/usr/share/doc/opencv-doc/examples/data/right[01]*.jpg \
	   $(REAL)/deb/x/usr/share/doc/opencv-doc/examples/data/aloe*.* \
	   $(REAL)/deb/x/usr/share/doc/opencv-doc/examples/data/intrinsics.yml $(REAL)/opencv/
	@rm -rf $(REAL)/deb && touch $@

notebooks: $(STAMP)
	$(PY) notebooks/execute.py

lint: $(STAMP)
	$(VENV)/bin/ruff check .

clean:
	rm -rf $(VENV) .pytest_cache demo-out .cache
