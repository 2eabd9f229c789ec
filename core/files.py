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
import logging
import os
import re
import secrets
import shutil
import sys
import tempfile
import threading
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
    "temp_prefix",
    "hold",
    "Busy",
    "scratch_dir",
    "stale_temporaries",
    "remove_stale",
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

    One writer at a time: the lock of ``path`` (:func:`hold`) is held from the check to
    the rename, so a second process writing the same folder raises :class:`Busy`.

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
    if not (path.exists() or path.is_symlink()):
        path.parent.mkdir(parents=True, exist_ok=True)  # a folder to hold the lock in
    with hold(path), _replace_dir(path) as tmp:
        yield tmp


@contextlib.contextmanager
def _replace_dir(path: Path) -> Iterator[Path]:
    _check_replaceable(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=temp_prefix(path), dir=path.parent))
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
        old = Path(tempfile.mkdtemp(prefix=temp_prefix(path, "old"), dir=path.parent))
        os.replace(path, old / "x")
    os.replace(tmp, path)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


#: the mark of scanamp's transient names: ``.NAME.scanamp-tmp-XXXXXXXX[.SUFFIX]`` (a file or
#: folder being written, renamed to NAME on success), ``.NAME.scanamp-old-XXXXXXXX`` (the
#: folder NAME replaced, removed right after), ``.NAME.scanamp-lock`` (the lock of NAME)
#: and ``.scanamp-scratch-XXXXXXXX`` (a run's scratch folder)
TAG = "scanamp"
_RANDOM = "[a-z0-9_]{8}"  # tempfile's random part
#: a temporary name inside a message or a path (the CLI shows the final name instead)
TEMP_NAME = re.compile(rf"\.([^/\s]+?)\.{TAG}-(?:tmp|old)-{_RANDOM}(?:\.[A-Za-z0-9]+(?![\w-]))?")
_TEMP_ENTRY = re.compile(
    rf"\.(?P<base>.+?)\.{TAG}-(?:tmp|old)-{_RANDOM}(?P<suffix>\.[^./]+)?")
_LOCK_ENTRY = re.compile(rf"\.(?P<base>.+)\.{TAG}-lock")
_SCRATCH_ENTRY = re.compile(rf"\.{TAG}-scratch-{_RANDOM}")


def temp_prefix(path: str | os.PathLike, kind: str = "tmp") -> str:
    """The prefix of a temporary sibling of ``path`` (``tempfile.mkdtemp(prefix=...,
    dir=path.parent)``): a name :func:`remove_stale` knows as ours."""
    return f".{Path(path).name}.{TAG}-{kind}-"


class Busy(InputError):
    """Another process holds the lock of this output (:func:`hold`)."""


# the locks this process holds: absolute path -> [pid, file descriptor, depth]
_HELD: dict[str, list] = {}
_HELD_GUARD = threading.Lock()


def _lock_path(path: Path) -> Path:
    return path.parent / f".{path.name}.{TAG}-lock"


@contextlib.contextmanager
def hold(path: str | os.PathLike, *, wait: bool = False) -> Iterator[None]:
    """Hold the advisory lock of ``path`` (``fcntl.flock`` on ``.NAME.scanamp-lock`` beside
    it): one writer per output across processes.

    Re-entrant within a process. Without ``wait``, a lock another process holds raises
    :class:`Busy` (an InputError naming ``path`` and that process); with it, the call
    waits its turn. The lock file is removed on release (and the kernel drops the lock of
    a killed process; :func:`remove_stale` removes its file), so nothing is left behind.
    Nothing is created to take the lock: a path whose folder does not exist yet (or
    cannot be written) is not locked here, and :func:`atomic_dir`, :func:`atomic_file`
    lock it once they have made its folder. On a file system (or an OS) without
    ``flock`` the lock is skipped.
    """
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX
        yield
        return
    path = Path(path)
    key = os.path.join(os.path.realpath(path.parent), path.name)  # one per lock file
    with _HELD_GUARD:
        held = _HELD.get(key)
        if held is not None and held[0] == os.getpid():
            held[2] += 1
            mine = False
        else:
            mine = True
    if not mine:
        try:
            yield
        finally:
            with _HELD_GUARD:
                _HELD[key][2] -= 1
        return
    lock = _lock_path(path)
    while True:
        try:
            fd = os.open(lock, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o666 & ~_umask())
        except OSError:  # no such folder yet (the writer that makes it locks there), or
            fd = None    # not ours to write in (the writer fails with its own message)
            break
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | (0 if wait else fcntl.LOCK_NB))
        except BlockingIOError:
            owner = os.pread(fd, 32, 0).decode(errors="replace").strip()
            os.close(fd)
            who = f" (pid {owner})" if owner.isdigit() else ""
            raise Busy(f"is being written by another scanamp process{who}; wait for it to "
                       "finish or choose another output (nothing was written)",
                       path=path) from None
        except OSError as exc:  # no flock here (some network file systems)
            os.close(fd)
            with contextlib.suppress(OSError):
                lock.unlink()
            logging.getLogger(__name__).debug("no lock for %s: %s", path, exc)
            fd = None
            break
        try:  # the file may have been removed by its last holder meanwhile: lock anew
            same = os.path.samestat(os.fstat(fd), os.stat(lock))
        except FileNotFoundError:
            same = False
        if same:
            os.ftruncate(fd, 0)
            os.pwrite(fd, str(os.getpid()).encode(), 0)
            break
        os.close(fd)
    with _HELD_GUARD:
        _HELD[key] = [os.getpid(), fd, 1]
    try:
        yield
    finally:
        with _HELD_GUARD:
            _HELD[key][2] -= 1
            last = _HELD[key][2] == 0
            if last:
                del _HELD[key]
        if last and fd is not None:
            with contextlib.suppress(FileNotFoundError):
                lock.unlink()  # while still locked: a waiter then finds it gone and retries
            os.close(fd)


@contextlib.contextmanager
def scratch_dir(parent: str | os.PathLike) -> Iterator[Path]:
    """A scratch folder ``PARENT/.scanamp-scratch-XXXXXXXX``, removed on success and on
    failure; one left by a killed process is removed by :func:`remove_stale` (a study does
    that when it resumes). Held (:func:`hold`) while in use, so a cleaner spares it."""
    parent = Path(parent)
    parent.mkdir(parents=True, exist_ok=True)
    while True:
        name = f".{TAG}-scratch-{secrets.token_hex(4)}"
        with hold(parent / name):
            try:
                (parent / name).mkdir()
            except FileExistsError:
                continue
            try:
                yield parent / name
            finally:
                shutil.rmtree(parent / name, ignore_errors=True)
            return


def _ours(entry: Path) -> Path | None:
    """The path whose lock guards ``entry`` if ``entry`` is one of our transient names."""
    name = entry.name
    m = _TEMP_ENTRY.fullmatch(name)
    if m and (m["suffix"] is None or m["base"].endswith(m["suffix"])):
        return entry.parent / m["base"]
    m = _LOCK_ENTRY.fullmatch(name)
    if m and entry.is_file() and not entry.is_symlink():
        return entry.parent / m["base"]
    if _SCRATCH_ENTRY.fullmatch(name) and entry.is_dir() and not entry.is_symlink():
        return entry
    return None


def stale_temporaries(folder: str | os.PathLike) -> list[Path]:
    """Our transient files and folders under ``folder`` (recursively; not inside one
    another) that no running process holds: what a killed run left behind.

    Only names that scanamp makes (:data:`TAG`) count: a user's ``notes.tmp`` or
    ``.draft.tmp-1`` is never one.
    """
    found = []
    for root, dirs, files in os.walk(folder):
        base = Path(root)
        for name in sorted(dirs + files):
            entry = base / name
            guard = _ours(entry)
            if guard is None:
                continue
            if name in dirs:
                dirs.remove(name)  # removed whole, not walked
            if not _busy(guard):
                found.append(entry)
        dirs.sort()
    return found


def _busy(path: Path) -> bool:
    """Whether some process holds the lock of ``path`` (a probe: creates nothing)."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX
        return False

    try:
        fd = os.open(_lock_path(path), os.O_RDWR | os.O_CLOEXEC)
    except FileNotFoundError:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        return True
    except OSError:  # no flock on this file system: nothing can be known to be in use
        return False
    finally:
        os.close(fd)  # closing drops a lock this probe took
    return False


def remove_stale(folder: str | os.PathLike) -> list[Path]:
    """Remove :func:`stale_temporaries` of ``folder``; returns what was removed."""
    removed = []
    for entry in stale_temporaries(folder):
        guard = _ours(entry)
        try:
            with hold(guard):  # not taken up by a new writer meanwhile
                if entry.is_dir() and not entry.is_symlink():
                    shutil.rmtree(entry)
                else:
                    entry.unlink(missing_ok=True)
        except Busy:
            continue
        removed.append(entry)
    return removed


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
    with hold(path, wait=True):  # concurrent writers of one file take turns
        fd, name = tempfile.mkstemp(prefix=temp_prefix(path), suffix=path.suffix,
                                    dir=path.parent)
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
