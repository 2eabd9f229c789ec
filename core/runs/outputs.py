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
whose inputs did not change can be skipped (:mod:`core.runs.stages`). One process writes an
output at a time: an advisory lock beside it is held from the check to the rename.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
from collections.abc import Iterator, Sequence
from pathlib import Path

from core.config import to_dict
from core.files import API, MANIFEST, atomic_dir, declare_output, hold, write_manifest
from core.validate import InputError

__all__ = ["read_manifest", "check_output", "check_output_file", "output_dir", "writing"]

@contextlib.contextmanager
def writing(path: str | os.PathLike, command: str, config=None) -> Iterator[None]:
    """Declare ``path`` as the output folder of ``command`` (run with ``config``, a
    :class:`core.config.Config`, if it has one) for the duration of a run.

    Any :func:`core.files.atomic_dir` that writes exactly ``path`` then adds the manifest
    and ``config.toml`` (:func:`core.files.write_declared`).
    """
    with declare_output(path, command, None if config is None else to_dict(config)):
        yield


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
