"""python/examples/paper_figures.py (issue 5) writes the paper's Figures 3–5 as PNG files."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

SCRIPT = Path(__file__).resolve().parents[1] / "examples" / "paper_figures.py"
FIGURES = ["fig3_joint1_response.png", "fig4_joint1_zoom.png", "fig5_l2_indices.png"]


def test_paper_figures_are_written(tmp_path: Path) -> None:
    pytest.importorskip("matplotlib")
    import matplotlib.image

    out = tmp_path / "figs"
    result = subprocess.run([sys.executable, str(SCRIPT), "--out-dir", str(out)], capture_output=True, text=True, check=False, timeout=120)
    assert result.returncode == 0, result.stdout + result.stderr
    assert "difference" in result.stdout
    for name in FIGURES:
        path = out / name
        assert path.is_file(), name
        assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", name
        assert path.stat().st_size > 10_000, name
        image = np.asarray(matplotlib.image.imread(path))
        assert image.shape[0] > 300 and image.shape[1] > 500, name
        # drawn on: many distinct colours, not a blank canvas
        assert len(np.unique(image.reshape(-1, image.shape[-1]), axis=0)) > 50, name
