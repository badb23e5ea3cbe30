"""The diagnosis' switches are one table (``simgap.DIAGNOSE_SWITCHES``): the CLI's flags, the
keywords of ``diagnose``, the type stub and the fleet's flags all have exactly its entries."""

from __future__ import annotations

import ast
import os
import subprocess
import sys
from pathlib import Path

import pytest

import simgap

ROOT = Path(__file__).resolve().parents[2]
STUB = ROOT / "python" / "simgap" / "_simgap.pyi"


def flags(help_text: str) -> set[str]:
    """The ``--flags`` named in a ``--help`` text."""
    return {w.strip(",[]") for w in help_text.split() if w.startswith("--")}


def test_the_table_names_each_switch_once_with_a_bool_default_and_help() -> None:
    names = [name for name, _, _ in simgap.DIAGNOSE_SWITCHES]
    assert names and len(names) == len(set(names)), names
    for name, default, help in simgap.DIAGNOSE_SWITCHES:
        assert name.isidentifier() and isinstance(default, bool) and len(help) > 20, (name, default, help)


def test_the_stub_lists_every_switch_as_a_keyword_with_its_default() -> None:
    tree = ast.parse(STUB.read_text())
    fn = next(n for n in tree.body if isinstance(n, ast.FunctionDef) and n.name == "diagnose")
    keywords = [a.arg for a in fn.args.kwonlyargs]
    names = [name for name, _, _ in simgap.DIAGNOSE_SWITCHES]
    defaults = {a.arg: d for a, d in zip(fn.args.kwonlyargs, fn.args.kw_defaults)}
    # the switches close the keywords (the inputs' own keywords, urdf, calibration, come first)
    assert keywords[-len(names) :] == names, "the stub's last diagnose keywords are the switches, in the table's order"
    assert not set(names) & set(keywords[: -len(names)]), "a switch listed twice"
    for name, default, _ in simgap.DIAGNOSE_SWITCHES:
        assert isinstance(defaults[name], ast.Constant) and defaults[name].value is default, name


def test_the_python_docs_list_every_switch() -> None:
    for name, default, _ in simgap.DIAGNOSE_SWITCHES:
        assert f"``{name}`` (default {default})" in (simgap.diagnose.__doc__ or ""), name


def test_the_cli_and_the_fleet_have_a_flag_per_switch() -> None:
    wanted = {"--" + name.replace("_", "-") for name, _, _ in simgap.DIAGNOSE_SWITCHES}
    binary = os.environ.get("SIMGAP_BIN") or str(ROOT / "target" / "release" / "simgap")
    if not Path(binary).is_file():
        if os.environ.get("CI"):
            pytest.fail(f"no simgap binary at {binary}: make test builds it and sets SIMGAP_BIN")
        pytest.skip(f"no simgap binary at {binary} (make test builds it)")
    cli = subprocess.run([binary, "diagnose", "--help"], capture_output=True, text=True, check=True).stdout
    assert wanted <= flags(cli), wanted - flags(cli)
    fleet = subprocess.run([sys.executable, "-m", "simgap.fleet", "--help"], capture_output=True, text=True, check=True).stdout
    assert wanted <= flags(fleet), wanted - flags(fleet)


def test_a_keyword_that_is_no_switch_or_not_a_bool_is_a_type_error() -> None:
    model = simgap.Model.paper_arm()
    with pytest.raises(TypeError, match="directional_frictoin.*directional_friction"):
        simgap.diagnose(model, [], [], directional_frictoin=True)
    with pytest.raises(TypeError, match="link_side_torque must be True or False, got int"):
        simgap.diagnose(model, [], [], link_side_torque=1)
