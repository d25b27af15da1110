# One entry point. Every target sets itself up first (tools/bootstrap.sh is idempotent)
# and keeps DDS discovery on this machine.
SHELL := /bin/bash
VENV ?= $(CURDIR)/.venv
PY := $(VENV)/bin/python
export ROS_AUTOMATIC_DISCOVERY_RANGE := LOCALHOST
unexport ROS_LOCALHOST_ONLY

.PHONY: setup test clean

setup:
	@EXTENDED_TRACKER_VENV=$(VENV) bash tools/bootstrap.sh

test: setup
	@unset ROS_LOCALHOST_ONLY; $(PY) -m pytest -q test

clean:
	rm -rf build out .pytest_cache .hypothesis
	rm -rf $(VENV)
