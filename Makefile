# Two commands do all set-up on a fresh machine with Python 3.11+: `make demo` and `make test`.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed-stamp

.PHONY: demo test bench install clean verify-unit browser curl mutate

# (Re)install when the dependency list changes; the project itself is installed editable.
$(STAMP): pyproject.toml
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test]'
	@touch $(STAMP)

install: $(STAMP)

demo: $(STAMP)
	$(PY) examples/demo.py

# Two workers by default (a build machine has 2 cores); TEST_WORKERS=0 runs in one process.
TEST_WORKERS ?= 2
test: $(STAMP) verify-unit browser curl
	$(PY) -m pytest -q -n $(TEST_WORKERS) --dist loadfile

# systemd-analyze verify on a copy of the unit whose ExecStart points into the venv (verify checks
# that the program exists; /usr/local/bin/ribbond does not on a build machine). Fails on errors and
# on any message about our unit; messages about other units on the machine are shown, not fatal.
# $(call need,TARGET,TEST,PACKAGE): when the shell test TEST fails, install Debian's PACKAGE (as
# root, with apt-get), else say how; fail if TEST still fails afterwards.
define need
	@if ! $(2); then \
	  if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then \
	    echo "$(1): $(3) missing, installing it"; \
	    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $(3) >/dev/null || exit 1; \
	  else \
	    echo "$(1): $(3) not found; install it (Debian/Ubuntu: sudo apt-get install $(3)) or run as root" >&2; \
	    exit 1; \
	  fi; \
	  $(2) || { echo "$(1): $(3) still missing after installing it" >&2; exit 1; }; \
	fi
endef

UNIT            := systemd/ribbond.service
SYSTEMD_ANALYZE ?= systemd-analyze
verify-unit: $(STAMP)
	$(call need,verify-unit,command -v $(SYSTEMD_ANALYZE) >/dev/null 2>&1,systemd)
	@venv='$(abspath $(VENV))'; \
	if [ -x "$$venv/bin/ribbond" ]; then exe="$$venv/bin/ribbond"; else exe="$$venv/bin/python -m ribbond"; fi; \
	tmp=$$(mktemp -d) && trap 'rm -rf "$$tmp"' EXIT && \
	sed "s|^ExecStart=/usr/local/bin/ribbond |ExecStart=$$exe |" $(UNIT) > "$$tmp/ribbond.service" && \
	if ! grep -q "^ExecStart=$$exe " "$$tmp/ribbond.service"; then \
	  echo "verify-unit: no 'ExecStart=/usr/local/bin/ribbond ' line to rewrite in $(UNIT)" >&2; exit 1; \
	fi; \
	opts="--man=no"; \
	if $(SYSTEMD_ANALYZE) verify --help 2>/dev/null | grep -q -- --recursive-errors; then \
	  opts="$$opts --recursive-errors=no"; recursive=no; else recursive=unsupported; fi; \
	out=$$($(SYSTEMD_ANALYZE) verify $$opts "$$tmp/ribbond.service" 2>&1); rc=$$?; \
	[ -z "$$out" ] || printf '%s\n' "$$out"; \
	ours=$$(printf '%s\n' "$$out" | grep -E "^($$tmp/)?ribbond\.service[:]"); \
	others=$$(printf '%s\n' "$$out" | grep -E '^[^ :]+\.(service|socket|target|timer|mount|automount|swap|path|slice|device)[:]'); \
	if [ -n "$$ours" ]; then echo "verify-unit: FAILED, $(UNIT) has the problems above" >&2; exit 1; fi; \
	if [ $$rc -ne 0 ]; then \
	  if [ $$recursive = unsupported ] && [ -n "$$others" ]; then \
	    echo "verify-unit: systemd-analyze failed on other units only (no --recursive-errors in this version); ignored"; \
	  else echo "verify-unit: FAILED, systemd-analyze verify exit status $$rc" >&2; exit 1; fi; \
	fi; \
	echo "verify-unit: $(UNIT) OK (systemd-analyze verify, ExecStart=$$exe)"

# The dashboard's browser tests (tests/web) run Debian's chromium through Playwright (pip, the test
# extra); `playwright install` is never run: browsers are not downloaded. Installed as root when missing.
CHROMIUM ?= /usr/bin/chromium
browser:
	$(call need,browser,test -x $(CHROMIUM),chromium)

# The slicer-upload tests send PrusaSlicer's request with curl (libcurl, as PrusaSlicer does).
curl:
	$(call need,curl,command -v curl >/dev/null 2>&1,curl)

bench: $(STAMP)
	$(PY) bench/stream.py
	$(PY) bench/flatten.py
	$(PY) bench/design.py
	$(PY) bench/accuracy.py
	$(PY) bench/deploy.py
	$(PY) bench/gcode.py
	$(PY) bench/daemon.py
	$(PY) bench/panels.py

# Mutation testing of the modules that keep the fabric and the printer safe (docs/mutation.md): mutmut
# (the `mutate` extra) over [tool.mutmut] only_mutate in pyproject.toml, with the fast tests listed
# there; one module at a time, niced, on MUTATE_WORKERS processes; then the share killed per module
# and the survivors (bench/mutation.py fails on a survivor not named equivalent, or on a name whose
# mutant was killed). mutmut keeps results in mutants/: `rm -rf mutants` first for figures to rely
# on. Not part of `make test`.
MUTATE_STAMP   := $(VENV)/.mutate-stamp
MUTATE_WORKERS ?= 1
MUTATE_MODULES ?= ribbond.daemon.jobs ribbond.gcode.profiles ribbond.daemon.components.frame \
                  ribbond.printer.proof ribbond.gcode.checker ribbond.printer.sender
$(MUTATE_STAMP): pyproject.toml $(STAMP)
	$(PY) -m pip install --quiet -e '.[test,mutate]'
	@touch $@

mutate: $(MUTATE_STAMP)
	@mkdir -p mutants
	@for module in $(MUTATE_MODULES); do \
	  echo "mutate: $$module (log: mutants/$$module.log)"; \
	  nice -n 10 $(VENV)/bin/mutmut run --max-children $(MUTATE_WORKERS) "$$module.*" \
	    > "mutants/$$module.log" 2>&1 || { tail -n 20 "mutants/$$module.log"; exit 1; }; \
	done
	$(PY) bench/mutation.py

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache out mutants
