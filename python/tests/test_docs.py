"""Every Python example in docs/guide/python.md runs: the code blocks, in order, in one namespace."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

DOC = Path(__file__).resolve().parents[2] / "docs" / "guide" / "python.md"


def python_blocks(text: str) -> list[str]:
    return re.findall(r"```python\n(.*?)```", text, flags=re.DOTALL)


def test_docs_have_python_examples() -> None:
    assert len(python_blocks(DOC.read_text(encoding="utf-8"))) >= 3


def test_every_python_example_in_the_docs_runs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    pytest.importorskip("matplotlib")
    monkeypatch.chdir(tmp_path)
    namespace: dict[str, object] = {"__name__": "__docs__"}
    for i, block in enumerate(python_blocks(DOC.read_text(encoding="utf-8"))):
        try:
            exec(compile(block, f"{DOC.name} block {i + 1}", "exec"), namespace)  # noqa: S102 - the docs' own code
        except Exception as e:  # noqa: BLE001 - name the block that failed
            raise AssertionError(f"docs/guide/python.md block {i + 1} failed: {e!r}\n{block}") from e
