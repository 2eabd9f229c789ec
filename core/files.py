"""Files: atomic outputs and config reading, shared by every package.

Outputs are written to a temporary sibling and renamed into place, so an
interrupted or failed run leaves no half-written file or folder. A folder written so
carries a manifest (:data:`MANIFEST`) naming the command that wrote it (the output
the running command declared, :func:`declare_output`) or the Python API. Config readers
raise :class:`core.validate.InputError` naming the file (and the field when
one is at fault).
"""

from __future__ import annotations

import contextlib
import contextvars
import json
import os
import shutil
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from core.validate import InputError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

__all__ = [
    "atomic_dir",
    "atomic_file",
    "write_json",
    "read_text",
    "read_json",
    "json_data",
    "read_toml",
    "write_toml",
    "require",
    "MANIFEST",
    "API",
    "CONFIG_FILE",
    "version",
    "write_manifest",
    "declared_manifest",
    "write_declared",
    "declare_output",
]


def _umask() -> int:
    """The process umask, read without changing it where the OS allows (thread safe)."""
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except OSError:  # pragma: no cover - not Linux
        pass
    mask = os.umask(0o022)  # pragma: no cover
    os.umask(mask)  # pragma: no cover
    return mask  # pragma: no cover


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
#: the output folder the running command declared (:func:`declare_output`): its resolved
#: path, the command, and the command's effective configuration as a TOML table (or None)
_DECLARED: contextvars.ContextVar[tuple[Path, str, dict | None] | None] = \
    contextvars.ContextVar("scanamp_declared_output", default=None)
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

    :func:`atomic_dir` calls this to put the manifest into the folder before
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
        write_toml(folder / CONFIG_FILE, declared[2])


@contextlib.contextmanager
def declare_output(path: str | os.PathLike, command: str,
                   config: dict | None = None) -> Iterator[None]:
    """Declare ``path`` as the output folder of ``command`` for the duration of a run:
    the folder :func:`atomic_dir` writes there gets that command's manifest and, when
    ``config`` (a TOML table) is given, ``config.toml`` (:func:`write_declared`).
    :func:`core.runs.outputs.writing` declares a command's output with its config."""
    token = _DECLARED.set((Path(path).resolve(), command, config))
    try:
        yield
    finally:
        _DECLARED.reset(token)


@contextlib.contextmanager
def atomic_dir(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary sibling folder; on success it replaces ``path``.

    On an exception the temporary folder is removed and ``path`` is left as it was.
    Only an empty folder or one scanamp wrote (with its manifest,
    :data:`MANIFEST`) is ever replaced: anything else at ``path`` raises
    InputError before anything is written. The folder gets the manifest: that of the
    running command when ``path`` is the output it declared (:func:`declare_output`),
    else one that says it was written through the Python API (``"command": "api"``).

    >>> import tempfile, pathlib
    >>> root = pathlib.Path(tempfile.mkdtemp())
    >>> with atomic_dir(root / "out") as tmp:
    ...     _ = (tmp / "a.txt").write_text("x")
    >>> sorted(p.name for p in (root / "out").iterdir())
    ['.scanamp.json', 'a.txt']
    """
    path = Path(path)
    _check_replaceable(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{path.name}.tmp-", dir=path.parent))
    try:
        yield tmp
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    os.chmod(tmp, 0o777 & ~_umask())  # mkdtemp makes 0700; outputs get the usual mode
    write_declared(tmp, path)  # the manifest (and config) of the command's declared output
    try:
        _check_replaceable(path)
    except InputError:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    old = None
    if path.exists():
        old = Path(tempfile.mkdtemp(prefix=f".{path.name}.old-", dir=path.parent))
        os.replace(path, old / "x")
    os.replace(tmp, path)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


def _check_replaceable(path: Path) -> None:
    """atomic_dir replaces only an empty folder or one scanamp wrote (never a file)."""
    if not (path.exists() or path.is_symlink()):
        return
    if path.is_dir() and not path.is_symlink() and (
            (path / MANIFEST).is_file() or not any(path.iterdir())):
        return
    raise InputError("exists and is not an empty folder or one scanamp wrote; nothing was "
                     "written (choose a new output folder)", path=path)


@contextlib.contextmanager
def atomic_file(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path beside ``path`` (same suffix); renamed into place on success.

    The file gets the mode a plain ``open(path, "w")`` would give (0666 under the
    umask, e.g. 0644), not the 0600 of a temporary file.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, name = tempfile.mkstemp(prefix=f".{path.stem}.tmp-", suffix=path.suffix, dir=path.parent)
    os.close(fd)
    tmp = Path(name)
    try:
        yield tmp
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    os.chmod(tmp, 0o666 & ~_umask())
    os.replace(tmp, path)


def _jsonable(obj: Any) -> Any:
    import numpy as np

    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"not JSON serializable: {type(obj).__name__}")


def json_data(data: Any) -> Any:
    """``data`` as :func:`write_json` writes it and :func:`read_json` gives it back: numpy
    arrays and tuples as lists, numpy scalars as Python numbers, paths as strings.

    >>> import numpy as np
    >>> json_data({"K": np.eye(2), "n": np.int64(3), "t": (1, 2)})
    {'K': [[1.0, 0.0], [0.0, 1.0]], 'n': 3, 't': [1, 2]}
    """
    return json.loads(json.dumps(data, default=_jsonable, allow_nan=True))


def write_json(path: str | os.PathLike, data: Any) -> Path:
    """Write ``data`` as indented JSON atomically (numpy arrays and scalars allowed)."""
    with atomic_file(path) as tmp:
        tmp.write_text(json.dumps(data, indent=2, default=_jsonable, allow_nan=True) + "\n")
    return Path(path)


def read_text(path: str | os.PathLike) -> str:
    """Read a UTF-8 text file; a missing or undecodable file raises InputError naming it."""
    path = Path(path)
    if not path.is_file():
        raise InputError("file not found", path=path)
    try:
        return path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise InputError(f"not UTF-8 text: {exc}", path=path) from None


def read_json(path: str | os.PathLike) -> Any:
    """Read JSON; a missing or malformed file raises InputError naming it."""
    path = Path(path)
    if not path.is_file():
        raise InputError("file not found", path=path)
    try:
        return json.loads(path.read_text())
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(f"malformed JSON: {exc}", path=path) from None


def read_toml(path: str | os.PathLike) -> dict:
    """Read TOML; a missing or malformed file raises InputError naming it."""
    path = Path(path)
    if not path.is_file():
        raise InputError("file not found", path=path)
    try:
        return tomllib.loads(path.read_text())
    except (UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise InputError(f"malformed TOML: {exc}", path=path) from None


def write_toml(path: str | os.PathLike, data: dict) -> Path:
    """Write ``data`` as TOML atomically."""
    import tomli_w

    with atomic_file(path) as tmp:
        tmp.write_bytes(tomli_w.dumps(data).encode())
    return Path(path)


def require(table: dict, key: str, kind: type | tuple[type, ...], *, path: Any = None,
            prefix: str = "", default: Any = ...) -> Any:
    """Fetch ``table[key]`` checked against ``kind``; InputError naming file and field.

    ``prefix`` is the dotted location of ``table`` (``"objects[2]"``), so the error
    names the full field (``objects[2].radius``). ``default`` makes the key optional.
    """
    field = f"{prefix}.{key}" if prefix else key
    if key not in table:
        if default is not ...:
            return default
        raise InputError("missing", path=path, field=field)
    value = table[key]
    kinds = kind if isinstance(kind, tuple) else (kind,)
    if float in kinds and isinstance(value, int) and not isinstance(value, bool):
        value = float(value)
    if isinstance(value, bool) and bool not in kinds:
        raise InputError(f"expected {_kind_name(kinds)}, got {value!r}", path=path, field=field)
    if not isinstance(value, kinds):
        raise InputError(f"expected {_kind_name(kinds)}, got {value!r}", path=path, field=field)
    return value


def _kind_name(kinds: tuple[type, ...]) -> str:
    names = {float: "a number", int: "an integer", str: "a string", bool: "true or false",
             list: "a list", dict: "a table"}
    return " or ".join(names.get(k, k.__name__) for k in kinds)
