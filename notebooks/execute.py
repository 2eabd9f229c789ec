"""Execute the walkthrough notebooks: in place (outputs stored for readers) or into a copy.

    python notebooks/execute.py                    # every notebook, outputs stored in place
    python notebooks/execute.py notebooks/01_laser_scanner.ipynb

Each notebook runs with a fresh temporary working directory, so the files it writes
(captures, reconstructions, renders) never land in the repository; the repository root is
put on the kernel's PYTHONPATH so the notebook imports this checkout's packages.
``tests/test_notebooks.py`` calls :func:`execute` on every notebook, so ``make test`` runs
them all.
"""

from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path

import nbformat
from nbclient import NotebookClient

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOKS = Path(__file__).resolve().parent


def notebooks() -> list[Path]:
    """The walkthrough notebooks, in reading order."""
    return sorted(NOTEBOOKS.glob("[0-9][0-9]_*.ipynb"))


def execute(path: Path, *, workdir: Path, timeout: int = 600) -> nbformat.NotebookNode:
    """Run every cell of the notebook at ``path`` with ``workdir`` as working directory.

    Returns the executed notebook; a failing cell raises ``nbclient.exceptions.CellExecutionError``
    naming the cell and the error.
    """
    nb = nbformat.read(path, as_version=4)
    env_path = os.environ.get("PYTHONPATH", "")
    os.environ["PYTHONPATH"] = os.pathsep.join(p for p in (str(ROOT), env_path) if p)
    os.environ.setdefault("NUMBA_THREADING_LAYER", "omp")
    try:
        client = NotebookClient(nb, timeout=timeout, kernel_name="python3",
                                resources={"metadata": {"path": str(workdir)}})
        client.execute()
    finally:
        os.environ["PYTHONPATH"] = env_path
    for cell in nb.cells:  # the kernel's start-up notice is not the notebook's output
        if cell.cell_type == "code":
            cell.outputs = [o for o in cell.outputs if not (
                o.get("name") == "stderr" and o.get("text", "").startswith("[IPKernelApp]"))]
    return nb


def main(argv: list[str]) -> int:
    paths = [Path(a) for a in argv] or notebooks()
    for path in paths:
        with tempfile.TemporaryDirectory() as tmp:
            nb = execute(path, workdir=Path(tmp))
        nbformat.write(nb, path)
        sys.stderr.write(f"executed {path}\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
