# Two commands do all set-up on a fresh machine: `make demo` and `make test`.
VENV    ?= .venv
PY      := $(VENV)/bin/python
STAMP   := $(VENV)/.installed
SYSLIBS := libusb-1.0-0 libgl1 libgomp1
OUT     ?= demo_out

.PHONY: demo test test-fast bench syslibs clean

demo: $(STAMP)
	$(VENV)/bin/workbench demo --out $(OUT)

test: $(STAMP)
	$(PY) -m pytest -q -n 2 tests

# while working: the suite without the tests marked slow (pyproject.toml lists the marker)
test-fast: $(STAMP)
	$(PY) -m pytest -q -n 2 -m "not slow" tests

bench: $(STAMP)
	$(PY) benchmarks/run_all.py

# open3d's wheel needs these system libraries (without libusb `import open3d` fails).
syslibs:
	@missing=""; for p in $(SYSLIBS); do \
	  dpkg-query -W -f='$${Status}' $$p 2>/dev/null | grep -q "ok installed" || missing="$$missing $$p"; \
	done; \
	if [ -n "$$missing" ]; then \
	  if [ "$$(id -u)" = "0" ] && command -v apt-get >/dev/null; then \
	    echo "installing system libraries:$$missing"; \
	    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $$missing; \
	  else \
	    echo "missing system libraries:$$missing"; \
	    echo "run: sudo apt-get update && sudo apt-get install -y$$missing"; exit 1; \
	  fi; \
	fi

$(STAMP): pyproject.toml | syslibs
	@test -x $(PY) || python3 -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e ".[test]"
	@touch $(STAMP)

clean:
	rm -rf $(VENV) $(OUT) .pytest_cache
