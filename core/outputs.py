"""Outputs that never destroy: where a command may write, and the manifest that says
a folder is ours.

A command's output folder must be new, an empty folder, or a folder that scanamp itself
wrote for the same command (its manifest, ``.scanamp.json``, names the command and the
version) together with ``overwrite=True``. An output is never the input, inside it, or a
folder that contains it. A single-file output must be new, or is replaced only with
``overwrite=True``. Everything else raises :class:`core.validate.InputError` with one
sentence that says what to do, before anything is written.

:func:`output_dir` checks, then yields a temporary sibling folder that replaces the
output on success (an interrupted or failed run leaves the old folder as it was); with
``reuse=True`` the temporary folder starts as a copy of the old one, so pipeline stages
whose inputs did not change can be skipped (:mod:`core.stages`). One process writes an
output at a time: an advisory lock beside it is held from the check to the rename.
"""

from __future__ import annotations

import contextlib
import contextvars
import json
import os
import shutil
from collections.abc import Iterator, Sequence
from pathlib import Path

from core.files import atomic_dir, hold
from core.validate import InputError

__all__ = ["MANIFEST", "read_manifest", "check_output", "check_output_file", "output_dir",
           "version", "writing", "write_manifest", "declared_manifest", "write_declared",
           "CONFIG_FILE"]

#: the manifest file inside every output folder scanamp writes
MANIFEST = ".scanamp.json"


def version() -> str:
    """scanamp's installed version ("unknown" when run from a bare checkout)."""
    from importlib import metadata

    try:
        return metadata.version("scanamp")
    except metadata.PackageNotFoundError:  # pragma: no cover - not installed
        return "unknown"


#: the "command" of a folder written through the Python API rather than the CLI
API = "api"
#: the output folder the running command declared (set by :func:`writing`)
_DECLARED: contextvars.ContextVar[tuple[Path, str, object] | None] = contextvars.ContextVar(
    "scanamp_declared_output", default=None)
#: the effective configuration of a command, beside its manifest in the output folder
CONFIG_FILE = "config.toml"


def _manifest(command: str) -> dict:
    # no time stamp: the same run gives the same bytes, the manifest included
    return {"format": "scanamp.output/1", "command": command, "version": version()}


def write_manifest(folder: str | os.PathLike, command: str) -> Path:
    """Write the manifest that marks ``folder`` as written by ``scanamp command``."""
    m = Path(folder) / MANIFEST
    m.write_text(json.dumps(_manifest(command), indent=2) + "\n")
    return m


def declared_manifest(path: str | os.PathLike) -> dict:
    """The manifest for folder ``path``: the running command's if ``path`` is the output it
    declared, else the Python API's (``"command": "api"``).

    :func:`core.files.atomic_dir` calls this to put the manifest into the folder before
    it is renamed into place, so a command's output is marked as ours atomically.
    """
    declared = _DECLARED.get()
    if declared is None or Path(path).resolve() != declared[0]:
        return _manifest(API)
    return _manifest(declared[1])


def write_declared(folder: str | os.PathLike, path: str | os.PathLike) -> None:
    """Into ``folder`` (the temporary folder that becomes ``path``), write the manifest and,
    when ``path`` is the running command's declared output and it has a config, the
    effective ``config.toml`` (re-running with ``--config`` it reproduces the output)."""
    folder = Path(folder)
    if not (folder / MANIFEST).exists():
        (folder / MANIFEST).write_text(json.dumps(declared_manifest(path), indent=2) + "\n")
    declared = _DECLARED.get()
    if declared is not None and declared[2] is not None and \
            Path(path).resolve() == declared[0] and not (folder / CONFIG_FILE).exists():
        from core.config import write_config

        write_config(folder / CONFIG_FILE, declared[2])


@contextlib.contextmanager
def writing(path: str | os.PathLike, command: str, config=None) -> Iterator[None]:
    """Declare ``path`` as the output folder of ``command`` (run with ``config``, a
    :class:`core.config.Config`, if it has one) for the duration of a run.

    Any :func:`core.files.atomic_dir` that writes exactly ``path`` then adds the manifest
    and ``config.toml`` (:func:`write_declared`).
    """
    token = _DECLARED.set((Path(path).resolve(), command, config))
    try:
        yield
    finally:
        _DECLARED.reset(token)


def read_manifest(path: str | os.PathLike) -> dict | None:
    """The manifest of a folder scanamp wrote, or None."""
    m = Path(path) / MANIFEST
    try:
        data = json.loads(m.read_text())
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) and isinstance(data.get("command"), str) else None


def _relation(out: Path, inputs: Sequence[str | os.PathLike]) -> tuple[str, Path] | None:
    ro = out.resolve()
    for inp in inputs:
        if inp is None:
            continue
        ri = Path(inp).resolve()
        if ro == ri:
            return "is the input", ri
        if ri in ro.parents:
            return "is inside the input", ri
        if ro in ri.parents:
            return "contains the input", ri
    return None


def _check_inputs(path: Path, inputs) -> None:
    rel = _relation(path, inputs)
    if rel is not None:
        what, inp = rel
        raise InputError(f"the output {what} {str(inp)!r}; choose another output path "
                         "(inputs are never written to)", path=path)


def check_output(path: str | os.PathLike, *, command: str,
                 inputs: Sequence[str | os.PathLike] = (), overwrite: bool = False) -> Path:
    """Check that folder ``path`` may be written by ``command``; InputError if not."""
    path = Path(path)
    _check_inputs(path, inputs)
    if not path.exists():
        if path.is_symlink():
            raise InputError("is a dangling symbolic link; choose a new folder", path=path)
        return path
    if not path.is_dir():
        raise InputError("exists and is not a folder; choose a new output folder "
                         "(nothing was written)", path=path)
    if not any(path.iterdir()):
        return path
    manifest = read_manifest(path)
    if manifest is None:
        raise InputError(f"is a folder scanamp did not write (no {MANIFEST}); choose a new "
                         "output folder (nothing was written)", path=path)
    if manifest["command"] != command:
        who = ("was written through scanamp's Python API" if manifest["command"] == API
               else f"holds the output of 'scanamp {manifest['command']}'")
        raise InputError(f"{who}, not by 'scanamp {command}'; choose a new output folder",
                         path=path)
    if not overwrite:
        raise InputError(f"exists (written by 'scanamp {command}'); pass --overwrite to "
                         "replace it, or choose a new output folder", path=path)
    return path


def check_output_file(path: str | os.PathLike, *, inputs: Sequence[str | os.PathLike] = (),
                      overwrite: bool = False) -> Path:
    """Check that file ``path`` may be written; InputError if not."""
    path = Path(path)
    _check_inputs(path, inputs)
    if path.is_dir():
        raise InputError("is a folder; expected a file path", path=path)
    if path.exists() and not overwrite:
        raise InputError("exists; pass --overwrite to replace it, or choose a new file",
                         path=path)
    if path.parent.exists() and not path.parent.is_dir():
        raise InputError(f"{str(path.parent)!r} is not a folder", path=path)
    return path


def _copy_into(src: Path, dst: Path) -> None:
    for item in src.iterdir():
        if item.name == MANIFEST:
            continue
        target = dst / item.name
        if item.is_dir() and not item.is_symlink():
            shutil.copytree(item, target, symlinks=True)
        else:
            shutil.copy2(item, target, follow_symlinks=False)


@contextlib.contextmanager
def output_dir(path: str | os.PathLike, *, command: str,
               inputs: Sequence[str | os.PathLike] = (), overwrite: bool = False,
               reuse: bool = False) -> Iterator[Path]:
    """Check ``path`` (:func:`check_output`), yield a temporary sibling, then write the
    manifest and rename it into place. The lock of ``path`` (:func:`core.files.hold`) is
    held throughout: a second writer of the same folder raises :class:`core.files.Busy`.

    Parameters
    ----------
    command : str
        What wrote the folder (``"reconstruct laser"``); a folder of another command is
        never replaced.
    inputs : sequence of path
        The command's inputs: the output may not be, be inside, or contain any of them.
    overwrite : bool
        Replace a folder this command wrote before.
    reuse : bool
        Start the temporary folder as a copy of that folder (stages skip unchanged work).
    """
    with hold(path):  # one writer from the check to the rename
        path = check_output(path, command=command, inputs=inputs, overwrite=overwrite)
        with atomic_dir(path) as tmp:
            if reuse and path.is_dir() and read_manifest(path) is not None:
                _copy_into(path, tmp)
            yield tmp
            write_manifest(tmp, command)
