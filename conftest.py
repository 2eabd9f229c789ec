"""Loaded before anything is collected, the package doctests included (``make test`` runs
``--doctest-modules`` over the library): the process-wide settings of tests/conftest.py
that must precede the first import of our packages, and the check that the tests leave
nothing in the system temporary directory.

The check: the session (the xdist controller, before it starts its workers) points
``TMPDIR`` at a private folder inside the system temporary directory, so everything the
tests, the library and their subprocesses put "in the temporary directory" lands there and
nothing of anyone else's does; at the end a non-empty folder fails the session, naming what
was left, and is removed; a folder a killed session left behind (its process gone) is
removed when the next session starts. pytest's own ``tmp_path`` folders (it keeps the last
three runs on purpose) live under the repository's ``.cache/pytest-tmp`` instead.
"""

import os
import shutil
import tempfile
from pathlib import Path

os.environ.setdefault("NUMBA_THREADING_LAYER", "omp")
# COLMAP's glog writes log files into the temporary directory unless told to use stderr,
# read when pycolmap loads: a test module importing pycolmap before our packages (whose
# core sets it too) must find it set already
os.environ.setdefault("GLOG_logtostderr", "1")

import cv2  # noqa: E402,F401  (cv2 before pycolmap: see DESIGN.md)
import pytest  # noqa: E402

_ROOT = Path(__file__).resolve().parent
_PRIVATE = "SCANAMP_TEST_TMPDIR"  # set by the controller, inherited by the workers


def pytest_configure(config):
    if os.environ.get("PYTEST_XDIST_WORKER") or _PRIVATE in os.environ:
        return  # a worker, or a pytest run inside a test: the controller's folder holds
    base = Path(os.environ.get("PYTEST_DEBUG_TEMPROOT") or _ROOT / ".cache" / "pytest-tmp")
    base.mkdir(parents=True, exist_ok=True)
    os.environ["PYTEST_DEBUG_TEMPROOT"] = str(base)
    _remove_dead_sessions(Path(tempfile.gettempdir()))
    private = tempfile.mkdtemp(prefix=f"scanamp-tests-{os.getpid()}-")
    os.environ[_PRIVATE] = os.environ["TMPDIR"] = tempfile.tempdir = private
    config._scanamp_tmp = Path(private)


def _remove_dead_sessions(tmp: Path) -> None:
    """Remove the private folders of test sessions whose process is gone (a run killed
    before its end cannot remove its own): ``scanamp-tests-PID-*``, PID no longer alive."""
    for folder in tmp.glob("scanamp-tests-*-*"):
        pid = folder.name.split("-")[2]
        if not pid.isdigit():
            continue
        try:
            os.kill(int(pid), 0)
        except ProcessLookupError:
            shutil.rmtree(folder, ignore_errors=True)
        except PermissionError:
            pass  # alive, someone else's


def pytest_sessionfinish(session, exitstatus):
    private = getattr(session.config, "_scanamp_tmp", None)
    if private is None:
        return
    left = sorted(p.name for p in private.iterdir()) if private.is_dir() else []
    shutil.rmtree(private, ignore_errors=True)
    if left:
        shown = ", ".join(left[:20]) + (f" (and {len(left) - 20} more)" if len(left) > 20 else "")
        rep = session.config.pluginmanager.get_plugin("terminalreporter")
        msg = f"the tests left {len(left)} item(s) in the temporary directory: {shown}"
        if rep is not None:
            rep.write_line(f"error: {msg}", red=True, bold=True)
        session.exitstatus = pytest.ExitCode.TESTS_FAILED


@pytest.fixture(autouse=True)
def _doctest_temp_folder(request):
    """A docstring example makes its folder with ``tempfile.mkdtemp()``, as a reader
    would; under pytest that folder is made in the example's own ``tmp_path``."""
    from _pytest.doctest import DoctestItem

    if not isinstance(request.node, DoctestItem):
        yield
        return
    saved = tempfile.tempdir
    tempfile.tempdir = str(request.getfixturevalue("tmp_path"))
    try:
        yield
    finally:
        tempfile.tempdir = saved
