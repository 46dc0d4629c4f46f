# Set-up and everyday commands. `make demo` and `make test` are all a fresh machine needs.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
JOBS ?= 2
# every package `make` installs, pinned with hashes: made from pyproject.toml by `make lock`
LOCK := requirements/test.lock
UV := uv==0.13.9
# where the CPU build of PyTorch lies on the machines we test on (requirements/overrides.txt)
FIND_LINKS := $(wildcard /opt/wheels)
# the newest releases pyproject.toml allows, for `make test-latest`
LATEST := .venv-latest

.PHONY: demo test install bench clean chromium docs lock test-latest

# the locked versions exactly (hash-checked, nothing resolved), then the package itself
$(STAMP): pyproject.toml setup.py $(LOCK)
	$(PY) -m venv $(VENV)
	$(BIN)/pip install -q --require-hashes --no-deps -r $(LOCK)
	$(BIN)/pip install -q --no-deps --no-build-isolation -e .
	$(BIN)/pip check
	touch $(STAMP)

install: $(STAMP)

demo: $(STAMP)
	$(BIN)/python -m ftrac_design.demo

# the report is tested in a real headless browser: Chromium from the system packages,
# installed here when missing and we are root (elsewhere the test skips, or fails under CI)
test: $(STAMP) chromium
	$(BIN)/python -m pytest -n $(JOBS) --dist loadgroup -q

# the lock again from pyproject.toml's ranges (the newest versions they allow today), with
# uv in a throw-away environment; commit the result after `make test` passes on it
lock:
	rm -rf .venv-lock && $(PY) -m venv .venv-lock && .venv-lock/bin/pip install -q $(UV)
	.venv-lock/bin/uv pip compile pyproject.toml --extra test --extra bench --universal \
		--python-version 3.11 --generate-hashes -q --override requirements/overrides.txt \
		$(if $(FIND_LINKS),--find-links $(FIND_LINKS)) -o $(LOCK)
	rm -rf .venv-lock

# the suite on the newest releases pyproject.toml allows (a separate venv, resolved now), with
# which packages moved from the lock; then the tracking tests on OpenCV 4.x in the same venv,
# and every pose of a fixed image set compared between OpenCV 5.x and 4.x
test-latest: chromium
	rm -rf $(LATEST) && $(PY) -m venv $(LATEST)
	$(LATEST)/bin/pip install -q --upgrade --upgrade-strategy eager -c requirements/overrides.txt -e ".[test,bench]"
	$(LATEST)/bin/pip freeze --all --exclude-editable > $(LATEST)/resolved.txt
	$(LATEST)/bin/python requirements/moved.py $(LOCK) $(LATEST)/resolved.txt
	$(LATEST)/bin/python -m pytest -n $(JOBS) --dist loadgroup -q
	$(LATEST)/bin/python tests/pose_record.py write $(LATEST)/poses-latest.json
	$(LATEST)/bin/pip install -q "opencv-python-headless>=4.9,<5"
	$(LATEST)/bin/pip freeze --all --exclude-editable > $(LATEST)/resolved-opencv4.txt
	$(LATEST)/bin/python requirements/moved.py $(LOCK) $(LATEST)/resolved-opencv4.txt
	$(LATEST)/bin/python -m pytest -n $(JOBS) -q tests/test_track.py tests/test_track_determinism.py \
		tests/test_segment.py tests/test_segment_conditioning.py tests/test_run_tracker.py tests/test_images_track.py
	$(LATEST)/bin/python tests/pose_record.py compare $(LATEST)/poses-latest.json

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
	rm -rf $(VENV) $(LATEST) outputs site
