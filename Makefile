# The two set-up commands of README.md: `make run` and `make test`.
# Both create the virtual environment in .venv on first use and re-install when
# pyproject.toml changes.

PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: run test lint typecheck pytest jstest pg chromium node bench clean

$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $(STAMP)

# exec: Ctrl-C or SIGTERM reaches the server itself, which shuts down and exits 0 ("stopped").
run: $(STAMP)
	exec $(BIN)/roverops serve --data-dir data

test: lint typecheck pytest jstest

lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .

typecheck: $(STAMP)
	$(BIN)/mypy estimation sim server sequences bench cli

pytest: $(STAMP) pg chromium
	$(BIN)/pytest

# The console's JavaScript unit tests (tests/js), Node's own runner; jsdom (Debian's
# node-jsdom, under /usr/share/nodejs) gives the DOM helper's test a W3C DOM.
jstest: node
	NODE_PATH=/usr/share/nodejs node --test tests/js/*.test.mjs

# PostgreSQL for the storage tests (tests/conftest.py starts a throwaway cluster from its
# binaries): Debian's package, installed once, `apt-get update` only if the install needs it.
PG_INSTALL := DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends \
	postgresql >/dev/null

pg:
	@ls /usr/lib/postgresql/*/bin/initdb >/dev/null 2>&1 || { \
	  test "$$(id -u)" = 0 || { echo "make pg: PostgreSQL missing; install it as root"; exit 0; }; \
	  echo "make pg: installing PostgreSQL (Debian package postgresql)"; \
	  $(PG_INSTALL) 2>/dev/null || { apt-get update -qq && $(PG_INSTALL); }; }

# Debian's Chromium for the browser tests (Playwright drives it; it never downloads one).
CHROMIUM_INSTALL := DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends \
	chromium >/dev/null

chromium:
	@test -x /usr/bin/chromium || { \
	  test "$$(id -u)" = 0 || { echo "make chromium: Chromium missing; install it as root"; exit 0; }; \
	  echo "make chromium: installing Chromium (Debian package chromium)"; \
	  $(CHROMIUM_INSTALL) 2>/dev/null || { apt-get update -qq && $(CHROMIUM_INSTALL); }; }

# Debian's Node.js and jsdom for the JavaScript tests (installed once, like Chromium).
NODE_INSTALL := DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends \
	nodejs node-jsdom >/dev/null

node:
	@{ command -v node >/dev/null && test -e /usr/share/nodejs/jsdom/package.json; } || { \
	  test "$$(id -u)" = 0 || { echo "make node: Node.js or jsdom missing; install them as root"; exit 0; }; \
	  echo "make node: installing Node.js and jsdom (Debian packages nodejs, node-jsdom)"; \
	  $(NODE_INSTALL) 2>/dev/null || { apt-get update -qq && $(NODE_INSTALL); }; }

bench: $(STAMP)
	$(BIN)/roverops bench sim --json

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache .mypy_cache .ruff_cache
