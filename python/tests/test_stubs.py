"""The type stubs match the extension module (mypy.stubtest) and the package exports."""

from __future__ import annotations

import subprocess
import sys

import simgap


def test_stubtest_passes() -> None:
    result = subprocess.run(
        [sys.executable, "-m", "mypy.stubtest", "simgap._simgap", "--ignore-missing-stub"],
        capture_output=True,
        text=True,
        check=False,
    )
    assert result.returncode == 0, result.stdout + result.stderr


def test_all_names_exist_and_are_documented() -> None:
    for name in simgap.__all__:
        obj = getattr(simgap, name)
        if name != "__version__":
            assert obj.__doc__, name
    assert "diagnose" in simgap.__all__
    assert "Report" in simgap.__all__


def test_every_public_method_has_a_docstring() -> None:
    for cls in (simgap.Model, simgap.Report):
        for name in dir(cls):
            if not name.startswith("_"):
                assert getattr(cls, name).__doc__, f"{cls.__name__}.{name}"
