"""The fleet example of docs/guide/fleet.md runs (a synthetic fleet on a LocalCluster of two workers)
and prints the findings the doc shows: the rising robot drifts, the payload robot carries an
effect the fleet does not have from day 3, no other robot is flagged."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("pandas")
pytest.importorskip("distributed")

DOC = Path(__file__).resolve().parents[2] / "docs" / "guide" / "fleet.md"
FINDING = re.compile(r"^\s*(arm-\d+)\s+(drift|step|effect|outlier)\s+(\S+)\s+(?:(\S+)\s+)?(\S+)\s+(\d{4}-\d\d-\d\d)\s*$")


def findings(text: str) -> list[tuple[str, ...]]:
    return [m.groups() for line in text.splitlines() if (m := FINDING.match(line))]


def test_example_prints_the_findings_of_the_doc(tmp_path: Path) -> None:
    proc = subprocess.run([sys.executable, "-m", "simgap.fleet.example", "--dir", str(tmp_path / "fleet"), "--html", str(tmp_path / "fleet.html")], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    got = findings(proc.stdout)
    assert got == [("arm-01", "drift", "coulomb_friction", "elbow", "fc", "2026-03-02"), ("arm-02", "effect", "payload", None, "mass", "2026-03-04")], proc.stdout
    block = DOC.read_text().split("python -m simgap.fleet.example", 1)[1]
    assert findings(block.split("30 robot-days on 2 workers in", 1)[0]) == got, "docs/guide/fleet.md shows what the example prints"
    assert "elbow Coulomb friction fc" in proc.stdout and "30 robot-days on 2 workers" in proc.stdout
    assert (tmp_path / "fleet.html").read_text().startswith("<!DOCTYPE html>")
