# One command runs every test, Rust and Python, on a fresh machine: `make test`.
# It checks formatting and lints (rustfmt, clippy -D warnings), creates .venv, installs
# requirements-test.txt and the simgap Python package, then runs cargo test (default members)
# and pytest.

PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
SIMGAP_BIN := $(CURDIR)/target/release/simgap
export CARGO_TERM_COLOR ?= never

.PHONY: test all-tests lint check-features bin rust-test rust-test-selfcheck selfcheck-build rust-test-rest python-test browser venv python-package demo bench compare-pinocchio clean

# Four jobs at a time, each job's output printed whole when it ends: the venv's installs
# (downloads, unpacking) overlap the Rust compilation, and the tests run in three streams, the
# blind self-check (its servo scenarios are the longest test: minutes), the other Rust tests and
# pytest, so that the two cores stay busy through what one stream leaves serial (a diagnosis's
# serial stages, Python's own work, process and cluster start-ups, the last long test of a
# binary). The fourth slot is the lints': with three, the self-check waited for clippy to end
# before it started (2 minutes in a CI run), and its stream ended alone. Cargo's lock on target/
# still compiles one thing at a time, and each stream starts as soon as what it runs is built.
# MAKEFLAGS is cleared for cargo and pytest: the jobserver of this make is not theirs.
test:
	@$(MAKE) --no-print-directory -j4 --output-sync=target all-tests

all-tests: venv lint rust-test-selfcheck python-test rust-test-rest

# Formatting and lints: `cargo fmt` as configured in rustfmt.toml, clippy with every warning an
# error (the workspace's deliberate exceptions are in Cargo.toml, with their reasons). Clippy
# checks in the release profile: the lints are the same (no code depends on debug_assertions),
# and the proc macros and build scripts it compiles (syn, serde_derive, pyo3's, the C of zstd and
# lz4) are then those of the release builds below, not compiled a second time for `dev`.
# check-features: every release build below asks its dependencies for the same features, so
# that they share one compilation (see .ci/check-features).
lint: check-features selfcheck-build
	cargo fmt --all -- --check
	MAKEFLAGS= cargo clippy --release --workspace --all-targets -- -D warnings

check-features:
	$(PYTHON) .ci/check-features

# Tests build in release: they share the artefacts of the CLI build (and of clippy's and
# maturin's, as check-features keeps it), and the diagnosis tests simulate and fit real runs (20x
# slower unoptimised).
# Both streams select the whole workspace (--workspace, as `cargo test` alone would), so that
# cargo resolves the same features and builds the tests once; the self-check binary runs in its
# own stream (`make test` runs it beside the others), the rest skips its tests by their exact
# names (a test added there and not listed here runs in both streams: twice, never not at all).
RUST_TEST := cargo test --release --workspace --exclude simgap-python
SELFCHECK_TESTS := fit_recovers_known_effects_in_blind_scenarios families_cycle_through_every_named_family \
  per_joint_gains_are_exchanged_for_the_inertial_correction_taken_first \
  servo_scenarios_find_the_hidden_mechanics_and_the_motor_constants real_drive_families_are_diagnosed_right_with_plausible_effects \
  encoder_offsets_on_servo_arms_are_found_and_not_invented backlash_on_servo_arms_is_found_and_not_invented

rust-test: rust-test-selfcheck rust-test-rest

rust-test-selfcheck: selfcheck-build browser
	cd crates/simgap-diag && SIMGAP_BIN=$(SIMGAP_BIN) "$$(cat $(SELFCHECK_EXE))"

# The self-check is the longest stream: its binary is built right after the CLI, before clippy
# (which waits for it, as every cargo waits for cargo's lock on target/), and run directly (its
# path from cargo's messages; a `cargo test` would wait for that lock again, behind clippy and
# the other builds), so that it starts minutes earlier and the lints run beside it. The other
# tests' build, started at the same moment, often takes the lock first and the self-check then
# starts after it; made to wait for the self-check's binary, a clean-clone run took 798 s
# against 716 and 771 s without the wait (four streams on two cores, pytest ending last): no
# gain, so the race stays.
SELFCHECK_EXE := $(CURDIR)/target/selfcheck_small.path
selfcheck-build: bin
	MAKEFLAGS= $(RUST_TEST) --test selfcheck_small --no-run --message-format=json-render-diagnostics | \
	  $(PYTHON) -c 'import json, sys; print(next(m["executable"] for m in map(json.loads, sys.stdin) if m.get("reason") == "compiler-artifact" and m.get("executable") and m["target"]["name"] == "selfcheck_small"))' > $(SELFCHECK_EXE)

rust-test-rest: bin browser
	MAKEFLAGS= SIMGAP_BIN=$(SIMGAP_BIN) $(RUST_TEST) -- --exact $(addprefix --skip ,$(SELFCHECK_TESTS))

# The CLI that the CLI tests of both suites run ($SIMGAP_BIN).
bin:
	MAKEFLAGS= cargo build --release --bin simgap

# Headless Chromium (Debian package `chromium`) for the test that renders the HTML report, when
# the system can install it (refreshing the package lists if the install fails without);
# without it that test skips with a message, and fails when `CI` is set.
browser:
	@command -v chromium >/dev/null 2>&1 || command -v chromium-browser >/dev/null 2>&1 || \
	  (export DEBIAN_FRONTEND=noninteractive; apt-get install -y -q chromium >/dev/null 2>&1 || \
	    (apt-get update -q >/dev/null 2>&1 && apt-get install -y -q chromium >/dev/null 2>&1)) || \
	  echo "headless Chromium is not available: the HTML rendering test will skip (and fail under CI)"

venv: $(VENV)/.requirements-stamp

$(VENV)/.requirements-stamp: requirements-test.txt
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -r requirements-test.txt
	touch $@

python-package: venv
	MAKEFLAGS= $(PY) -m pip install --quiet ./python

python-test: python-package bin
	MAKEFLAGS= SIMGAP_BIN=$(SIMGAP_BIN) $(PY) -m pytest -q python/tests tests/python

demo:
	cargo run --release -- demo

bench:
	cargo bench --bench dynamics

compare-pinocchio: venv
	cargo build --release --example timings
	$(PY) scripts/compare_pinocchio.py

clean:
	rm -rf $(VENV) target
