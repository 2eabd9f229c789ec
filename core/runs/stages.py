"""Named pipeline stages that are skipped when their inputs and options have not changed.

A pipeline is a short list of stages. Each stage's result is stored in the output folder
(``stages/NAME.pkl``, with ``stages/NAME.json`` holding the key it was computed for); the
key hashes what the stage depends on: its options, the files it reads, and the keys of
the stages before it. Running the pipeline again into the same folder recomputes only the
stages whose key changed and those after them; ``from_stage`` forces a stage and the
ones after it to run. A user who changes the Poisson depth re-runs the meshing, not the
calibration.

The stored results are Python pickles: a cache for this version of scanamp, never an
exchange format (the outputs the user reads are the pipeline's own files). A pickle is
only ever loaded when its HMAC, made with a secret kept in the user's cache folder
(``~/.cache/scanamp/stage-key``, mode 0600), matches: a cache from another machine or
user, or one that was edited, is recomputed rather than unpickled. So is one that cannot
be read, or was written by another version.

>>> import tempfile, pathlib
>>> folder = pathlib.Path(tempfile.mkdtemp())
>>> calls = []
>>> def double(x):
...     calls.append(x)
...     return 2 * x
>>> runner = Stages(folder, ["a", "b"])
>>> runner.run("a", double, 21, depends={"x": 21})
42
>>> Stages(folder, ["a", "b"]).run("a", double, 21, depends={"x": 21})  # from the cache
42
>>> calls
[21]
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import pickle
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import Any

from core.validate import check_choice

__all__ = ["Stages", "files_key"]

log = logging.getLogger(__name__)


def _version() -> str:
    from core.files import version

    return version()


def _secret() -> bytes:
    """This user's key for the caches' HMACs (created on first use, readable by them only)."""
    base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "scanamp"
    path = base / "stage-key"
    try:
        return path.read_bytes()
    except OSError:
        pass
    base.mkdir(parents=True, exist_ok=True)
    key = os.urandom(32)
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    with os.fdopen(fd, "wb") as fh:
        fh.write(key)
    return key


def _mac(data: bytes) -> str:
    import hmac

    return hmac.new(_secret(), data, hashlib.sha256).hexdigest()


def files_key(paths: Iterable[str | os.PathLike]) -> list:
    """What identifies input files cheaply: name, size and modification time of each."""
    out = []
    for p in paths:
        st = Path(p).stat()
        out.append([str(p), st.st_size, st.st_mtime_ns])
    return out


def _copy_files(src: Path, dst: Path, files: Sequence[str]) -> None:
    import shutil

    for f in files:
        a, b = src / f, dst / f
        b.parent.mkdir(parents=True, exist_ok=True)
        if a.is_dir():
            shutil.copytree(a, b, dirs_exist_ok=True)
        else:
            shutil.copy2(a, b)


class Stages:
    """Runs named stages in ``folder/stages`` (see the module docstring).

    Parameters
    ----------
    folder : path
        Where the cache lives (the pipeline's output folder, or its temporary twin).
    order : sequence of str
        The stages' names in pipeline order.
    from_stage : str, optional
        Run this stage and every later one even if cached.
    reuse : path, optional
        An earlier output folder whose ``stages/`` cache may be used (read only).
    """

    def __init__(self, folder: str | os.PathLike, order: Sequence[str], *,
                 from_stage: str | None = None, reuse: str | os.PathLike | None = None):
        self.folder = Path(folder) / "stages"
        self.order = list(order)
        if from_stage is not None:
            check_choice(from_stage, "from_stage", self.order)
        self.forced = set(self.order[self.order.index(from_stage):]) if from_stage else set()
        self.reuse = None if reuse is None else Path(reuse) / "stages"
        self.keys: dict[str, str] = {}
        self.ran: list[str] = []
        self.skipped: list[str] = []

    def _key(self, name: str, depends: Any) -> str:
        upstream = {n: self.keys[n] for n in self.order[:self.order.index(name)]
                    if n in self.keys}
        text = json.dumps({"stage": name, "version": _version(), "depends": depends,
                           "upstream": upstream}, sort_keys=True, default=str)
        return hashlib.sha256(text.encode()).hexdigest()

    def _load(self, name: str, key: str):
        for base in (self.folder, self.reuse):
            if base is None:
                continue
            try:
                meta = json.loads((base / f"{name}.json").read_text())
                if meta.get("key") != key:
                    continue
                data = (base / f"{name}.pkl").read_bytes()
                import hmac

                if not hmac.compare_digest(str(meta.get("hmac", "")), _mac(data)):
                    log.debug("stage %s: cache not signed by this user; recomputed", name)
                    continue
                return True, pickle.loads(data), base
            except (OSError, ValueError, pickle.UnpicklingError, EOFError, AttributeError,
                    ImportError):
                continue
        return False, None, None

    def run(self, name: str, fn: Callable, *args, depends: Any = None,
            files: Sequence[str] = (), **kwargs):
        """``fn(*args, **kwargs)``, or its stored result when ``depends`` (JSON-able: the
        options and input files it reads) and the earlier stages are unchanged.

        ``files`` are the paths (relative to the pipeline's folder; files or folders) the
        stage writes: a stored result is used only when they are all there, and taken
        from an earlier output folder they are copied along with it."""
        check_choice(name, "stage", self.order)
        key = self._key(name, depends)
        self.keys[name] = key
        if name not in self.forced:
            found, value, base = self._load(name, key)
            if found and not all((base.parent / f).exists() for f in files):
                log.debug("stage %s: its files are gone; recomputed", name)
                found = False
            if found:
                if base != self.folder:
                    _copy_files(base.parent, self.folder.parent, files)
                    self._store(name, key, value)
                self.skipped.append(name)
                log.debug("stage %s: unchanged, reused", name)
                return value
        value = fn(*args, **kwargs)
        self._store(name, key, value)
        self.ran.append(name)
        return value

    def _store(self, name: str, key: str, value) -> None:
        self.folder.mkdir(parents=True, exist_ok=True)
        data = pickle.dumps(value, protocol=pickle.HIGHEST_PROTOCOL)
        (self.folder / f"{name}.pkl").write_bytes(data)
        (self.folder / f"{name}.json").write_text(json.dumps(
            {"stage": name, "key": key, "hmac": _mac(data)}, indent=2) + "\n")
