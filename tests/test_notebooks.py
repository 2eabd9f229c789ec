"""Every walkthrough notebook runs from top to bottom (``make test`` executes them all)."""

import importlib.util
from pathlib import Path

import pytest

_spec = importlib.util.spec_from_file_location(
    "notebooks_execute", Path(__file__).resolve().parents[1] / "notebooks" / "execute.py")
_execute = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_execute)


@pytest.mark.slow
@pytest.mark.parametrize("path", _execute.notebooks(), ids=lambda p: p.stem)
def test_notebook_runs_top_to_bottom(path, tmp_path):
    nb = _execute.execute(path, workdir=tmp_path)
    code = [c for c in nb.cells if c.cell_type == "code"]
    assert code, f"{path.name} has no code cells"
    errors = [o for c in code for o in c.get("outputs", []) if o.get("output_type") == "error"]
    assert not errors, f"{path.name}: {errors[0].get('ename')}: {errors[0].get('evalue')}"



def test_the_seven_walkthroughs_are_shipped_with_their_outputs():
    paths = _execute.notebooks()
    assert [p.stem[:2] for p in paths] == ["01", "02", "03", "04", "05", "06", "07"], paths
    import nbformat

    for path in paths:  # stored executed, so a reader sees the plots without running them
        nb = nbformat.read(path, as_version=4)
        images = [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])
                  if "image/png" in o.get("data", {})]
        assert images, f"{path.name} is stored without its figures"
