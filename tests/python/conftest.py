"""Shared fixtures of the cross-tool tests: the simgap CLI they run."""

from __future__ import annotations

import os

import pytest


@pytest.fixture(scope="session")
def simgap_bin() -> str:
    """The simgap CLI (`SIMGAP_BIN`, which `make test` sets); without it a test fails under CI
    and skips elsewhere."""
    binary = os.environ.get("SIMGAP_BIN")
    if not binary:
        if os.environ.get("CI"):
            pytest.fail("SIMGAP_BIN is not set: CI must build the CLI (cargo build --release --bin simgap) and set it")
        pytest.skip("SIMGAP_BIN is not set (cargo build --release --bin simgap; SIMGAP_BIN=$PWD/target/release/simgap)")
    return binary
