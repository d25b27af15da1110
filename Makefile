# One entry point. Every target sets itself up first (tools/bootstrap.sh is idempotent)
# and keeps DDS discovery on this machine.
SHELL := /bin/bash
VENV ?= $(CURDIR)/.venv
PY := $(VENV)/bin/python
export ROS_AUTOMATIC_DISCOVERY_RANGE := LOCALHOST
unexport ROS_LOCALHOST_ONLY

.PHONY: setup test test-fast shape demo real bench results config clean

setup:
	@EXTENDED_TRACKER_VENV=$(VENV) bash tools/bootstrap.sh

test: setup
	@unset ROS_LOCALHOST_ONLY; $(PY) -m pytest -q test

# everything but the tests marked slow (real recordings, soaks): under a minute
test-fast: setup
	@unset ROS_LOCALHOST_ONLY; $(PY) -m pytest -q -m 'not slow' test

shape:
	@python3 tools/check_shape.py

REAL := ../shared/data/real
TRACKER := $(VENV)/bin/extended-tracker

demo: setup
	@rm -rf out/demo && mkdir -p out/demo
	$(TRACKER) replay bags/demo --output out/demo/demo_tracks --plot out/demo/demo.png
	@if [ -d $(REAL)/legtracker_demo_stationary_simple_environment ]; then \
	  echo; echo 'real recording: leg_tracker demo (people at leg height, walls, furniture)'; \
	  $(TRACKER) replay $(REAL)/legtracker_demo_stationary_simple_environment \
	    --output out/demo/legtracker_tracks --plot out/demo/legtracker.png; \
	fi

real: setup
	$(TRACKER) real --data $(REAL) --out out/real --mounts-dir config/mounts

bench: setup
	$(TRACKER) bench --memory 20000

results: setup
	$(TRACKER) results --readme doc/results.md

config: setup
	$(PY) -m extended_tracker.configio > config/tracker.yaml
	$(PY) -m extended_tracker.configio leg_height > config/leg_height.yaml
	$(PY) -m extended_tracker.configio --readme README.md

clean:
	rm -rf build out .pytest_cache .hypothesis
	rm -rf $(VENV)
