# Set-up and everyday commands. `make demo` and `make test` are all a fresh machine needs.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
JOBS ?= 2

.PHONY: demo test install bench clean chromium docs

$(STAMP): pyproject.toml
	$(PY) -m venv $(VENV)
	$(BIN)/pip install -q --upgrade pip
	$(BIN)/pip install -q -e ".[test,bench]"
	touch $(STAMP)

install: $(STAMP)

demo: $(STAMP)
	$(BIN)/python -m ftrac_design.demo

# the report is tested in a real headless browser: Chromium from the system packages,
# installed here when missing and we are root (elsewhere the test skips, or fails under CI)
test: $(STAMP) chromium
	$(BIN)/python -m pytest -n $(JOBS) --dist loadgroup -q

chromium:
	@command -v chromium >/dev/null 2>&1 || command -v chromium-browser >/dev/null 2>&1 || \
	if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then \
		(apt-get update -q && DEBIAN_FRONTEND=noninteractive apt-get install -y -q chromium) || \
		echo "warning: chromium could not be installed; the report's browser test will fail under CI"; \
	else echo "note: chromium not found and not root; the report's browser tests will skip (fail under CI)"; fi

# the documentation site into site/; --strict: a broken link, reference or docstring fails it
docs: $(STAMP)
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs build --strict -d site

bench: $(STAMP)
	for f in benchmarks/*.py; do $(BIN)/python $$f || exit 1; done

clean:
	rm -rf $(VENV) outputs site
