# The two README commands: `make demo` and `make test`. Nothing clever.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: demo test test-fast install system-deps lint api-types clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip

$(STAMP): $(BIN)/python pyproject.toml
	$(BIN)/pip install --quiet -e '.[test]'
	touch $(STAMP)

# axe-core (accessibility rules) for the browser tests' page audit, pinned, from the npm registry
# into a cache folder of the checkout; stamped so it runs once. Without npm the audit skips (fails
# under CI) and `install` still succeeds.
AXE_VERSION := 4.10.3
AXE_DIR     := .cache/npm
AXE_STAMP   := $(AXE_DIR)/.axe-core-$(AXE_VERSION)

$(AXE_STAMP):
	@if command -v npm >/dev/null; then \
	  npm install --prefix $(AXE_DIR) --no-save --no-audit --no-fund --loglevel=error axe-core@$(AXE_VERSION) \
	    && touch $(AXE_STAMP) \
	    || echo "note: could not install axe-core with npm; the page audit will skip (fail under CI)"; \
	else echo "note: npm missing; the page audit will skip (fail under CI)"; fi

# TypeScript's checker for the dashboard's JSDoc types (frontend/tsconfig.json: every module, strict; the API's
# answers typed by frontend/js/api-types.d.ts, `make api-types`), pinned, from the npm registry into a cache
# folder of its own (an install beside axe-core could prune it); stamped. Without npm `make lint` skips the
# check with a note (fails under CI=true).
TSC_VERSION := 5.9.3
TSC_DIR     := .cache/npm-tsc
TSC_STAMP   := $(TSC_DIR)/.typescript-$(TSC_VERSION)
TSC         := $(TSC_DIR)/node_modules/.bin/tsc

$(TSC_STAMP):
	@if command -v npm >/dev/null; then \
	  npm install --prefix $(TSC_DIR) --no-save --no-audit --no-fund --loglevel=error typescript@$(TSC_VERSION) \
	    && touch $(TSC_STAMP) \
	    || echo "note: could not install typescript with npm; the JSDoc type check will skip (fail under CI)"; \
	else echo "note: npm missing; the JSDoc type check will skip (fail under CI)"; fi

# The compose CLI from PyPI (docker-compose 1.29.2: its `config` needs no Docker daemon) for the check of
# docker-compose.yml, in a venv of its own: it pins PyYAML<6 (built here with Cython<3, having no wheel for
# this Python) and jsonschema<4, which the project's venv must not take. Stamped; a failure only notes.
COMPOSE_VENV  := .cache/compose-venv
COMPOSE_STAMP := $(COMPOSE_VENV)/.docker-compose-1.29.2

$(COMPOSE_STAMP):
	@($(PYTHON) -m venv $(COMPOSE_VENV) \
	  && $(COMPOSE_VENV)/bin/pip install --quiet "cython<3" wheel setuptools \
	  && $(COMPOSE_VENV)/bin/pip install --quiet --no-build-isolation "pyyaml==5.4.1" \
	  && $(COMPOSE_VENV)/bin/pip install --quiet "docker-compose==1.29.2" \
	  && touch $(COMPOSE_STAMP)) \
	  || echo "note: could not install docker-compose 1.29.2; the compose file check will skip (fail under CI)"

install: $(STAMP) $(AXE_STAMP) $(COMPOSE_STAMP)

# Debian's chromium for the dashboard's browser tests (never a downloaded browser); Debian's haproxy for
# the proxy tests (tests/deploy).
system-deps:
	@if [ ! -x /usr/bin/chromium ]; then \
	  if [ "$$(id -u)" = "0" ] && command -v apt-get >/dev/null; then \
	    (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium chromium-driver >/dev/null) \
	      || echo "note: could not install chromium; browser tests will skip (fail under CI)"; \
	  else echo "note: /usr/bin/chromium missing; browser tests will skip (fail under CI)"; fi; \
	fi
	@if ! command -v haproxy >/dev/null; then \
	  if [ "$$(id -u)" = "0" ] && command -v apt-get >/dev/null; then \
	    (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq haproxy >/dev/null) \
	      || echo "note: could not install haproxy; the proxy tests will skip (fail under CI)"; \
	  else echo "note: haproxy missing; the proxy tests will skip (fail under CI)"; fi; \
	fi

demo: install
	$(BIN)/saddlescope demo $(if $(PORT),--port $(PORT),)

lint: install $(TSC_STAMP)
	$(BIN)/ruff check backend worker tests
	$(BIN)/lint-imports --config pyproject.toml
	$(BIN)/mypy  # [tool.mypy] in pyproject.toml: the saddlescope package, the core strict
	@if [ -x $(TSC) ]; then echo "$(TSC) -p frontend/tsconfig.json"; $(TSC) -p frontend/tsconfig.json; \
	elif [ "$$CI" = "true" ]; then echo "typescript is missing (npm?): the JSDoc type check cannot run under CI" >&2; exit 1; \
	else echo "note: typescript missing (npm?); skipped the JSDoc type check (frontend/tsconfig.json)"; fi

# The dashboard's types of the API's answers (frontend/js/api-types.d.ts), written from the API's own OpenAPI
# schema; tests/api/test_api_frontend_types.py fails while the file is older than the schemas.
api-types: install
	$(BIN)/python -m saddlescope.api.frontend_types

# Three pytest-xdist workers on two cores, each test file whole on one worker (--dist loadfile: a module's
# server, ride or database is built once): a third of the suite's time is waiting (servers, browser, broker,
# the drills' outages), and a third worker computes meanwhile. Files are handed out heaviest first in
# tests/conftest.py's order (--no-loadscope-reorder: xdist's own order, most tests first, left the few-test
# heavy files to the end with a worker idle). TEST_WORKERS=0 runs everything in one process.
TEST_WORKERS ?= 3
XDIST := -n $(TEST_WORKERS) --dist loadfile --no-loadscope-reorder

test: install system-deps lint
	$(BIN)/python -m pytest $(XDIST)

# The inner loop: every test but the slow ones (whole rendered rides), the browser's and those needing
# PostgreSQL, Redis, a Celery worker or an S3 server (markers slow, browser, integration). `make test` runs
# everything, and is what CI runs.
FAST_TESTS := not slow and not browser and not integration

test-fast: install
	$(BIN)/python -m pytest $(XDIST) -m "$(FAST_TESTS)"

clean:
	rm -rf $(VENV) var .cache/npm .cache/npm-tsc
