"""Runs that leave nothing behind and one writer per output: the output lock
(core.files.hold), scratch folders, ``scanamp clean``, and a study killed with SIGKILL
then resumed with a private TMPDIR."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from core.files import Busy, hold, remove_stale, scratch_dir, stale_temporaries
from scanamp.cli import main

ROOT = Path(__file__).resolve().parents[1]


def _env(**extra):
    return {**os.environ, "PYTHONPATH": str(ROOT), **extra}


def _wait_for(cond, proc, what, timeout=120.0):
    deadline = time.monotonic() + timeout
    while not cond():
        assert proc.poll() is None, f"the process ended before {what}"
        assert time.monotonic() < deadline, f"no {what} in time"
        time.sleep(0.02)


def _ours(folder: Path) -> list[str]:
    """Every name of scanamp's transient kinds under ``folder``."""
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*")
                  if "scanamp-" in p.name)


HOLDER = """
import os, sys, time
from pathlib import Path
from core.runs.outputs import output_dir
out, ready, go = map(Path, sys.argv[1:4])
with output_dir(out, command="scene") as tmp:
    (tmp / "a.txt").write_text("first")
    ready.touch()
    while not go.exists():
        time.sleep(0.02)
"""


def test_a_second_process_on_the_same_output_exits_2_and_nothing_is_lost(tmp_path):
    out, ready, go = tmp_path / "out", tmp_path / "ready", tmp_path / "go"
    first = subprocess.Popen([sys.executable, "-c", HOLDER, str(out), str(ready), str(go)],
                             env=_env(), stderr=subprocess.PIPE, text=True)
    try:
        _wait_for(ready.exists, first, "lock taken")
        second = subprocess.run([sys.executable, "-m", "scanamp", "scene", "object", "--out",
                                 str(out)], env=_env(), capture_output=True, text=True,
                                timeout=300)
    finally:
        go.touch()
    assert first.wait(timeout=120) == 0, first.stderr.read()
    assert second.returncode == 2
    lines = second.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"error: {out}: is being written by "
                                                   f"another scanamp process (pid {first.pid})")
    # the first writer's output is whole; no lock file or temporary is left
    assert (out / "a.txt").read_text() == "first"
    assert json.loads((out / ".scanamp.json").read_text())["command"] == "scene"
    assert _ours(tmp_path) == []


def test_the_lock_is_reentrant_released_and_survives_no_kill(tmp_path):
    out = tmp_path / "out"
    lock = tmp_path / ".out.scanamp-lock"
    with hold(out):
        with hold(out):  # the same process: re-entrant
            assert lock.is_file() and lock.read_text() == str(os.getpid())
        assert lock.is_file()
    assert not lock.exists()
    # a holder killed outright leaves its lock file, but not its lock
    proc = subprocess.Popen([sys.executable, "-c", "import sys, time\nfrom core.files import "
                             "hold\nwith hold(sys.argv[1]):\n    print('held', flush=True)\n"
                             "    time.sleep(600)", str(out)], env=_env(),
                            stdout=subprocess.PIPE, text=True)
    assert proc.stdout.readline().strip() == "held"
    with pytest.raises(Busy, match=f"pid {proc.pid}"):
        with hold(out):
            pass
    assert stale_temporaries(tmp_path) == []  # in use: not stale
    proc.kill()
    proc.wait()
    assert lock.is_file()
    assert remove_stale(tmp_path) == [lock]
    with hold(out):
        pass
    assert not lock.exists()


def test_scratch_folders_go_on_success_and_on_failure(tmp_path):
    with scratch_dir(tmp_path) as s:
        (s / "x").write_text("x")
        assert s.parent == tmp_path and s.name.startswith(".scanamp-scratch-")
        assert stale_temporaries(tmp_path) == []  # held while in use
    with pytest.raises(RuntimeError):
        with scratch_dir(tmp_path) as s:
            raise RuntimeError("boom")
    assert list(tmp_path.iterdir()) == []


def test_clean_removes_ours_and_only_ours(tmp_path, capsys):
    ours = [".mesh.ply.scanamp-tmp-abcd1234.ply", ".rec.scanamp-tmp-k2j4_x9q/",
            ".rec.scanamp-old-efgh5678/", ".rec.scanamp-lock", "sub/.scanamp-scratch-0123abcd/",
            "sub/deeper/.r.json.scanamp-tmp-zz00zz00.json"]
    users = [".mesh.tmp-abcd1234", ".mesh.ply.tmp-abcd1234.ply", "notes.scanamp-tmp-abcd1234",
             ".rec.scanamp-tmp-abc", ".x.ply.scanamp-tmp-abcd1234.txt", "scanamp-run-mine/",
             ".scanamp-scratch-notes/", "sub/.scanamp-scratch-4567cdef", ".rec.scanamp-lock.bak",
             "rec/", ".scanamp.json", ".busy.scanamp-tmp-q1w2e3r4/"]
    for name in ours + users:
        p = tmp_path / name
        p.parent.mkdir(parents=True, exist_ok=True)
        if name.endswith("/"):
            p.mkdir()
            (p / "inside.txt").write_text("data")
        else:
            p.write_text("data")
    expected = sorted(tmp_path / n.rstrip("/") for n in ours)
    with hold(tmp_path / "busy"):  # a temporary in use is never stale
        assert main(["clean", str(tmp_path), "--dry-run"]) == 0
        assert sorted(Path(x) for x in capsys.readouterr().out.split()) == expected
        assert all((tmp_path / n).exists() for n in ours)
        assert main(["clean", str(tmp_path)]) == 0
        assert sorted(Path(x) for x in capsys.readouterr().out.split()) == expected
    assert not any((tmp_path / n).exists() for n in ours)
    for name in users:
        p = tmp_path / name
        assert (p / "inside.txt").read_text() == "data" if name.endswith("/") else \
            p.read_text() == "data"
    assert main(["clean", str(tmp_path / "missing")]) == 2


KILL = """
[study]
name = "kill"
kind = "_test"
[base]
sleep = 1.0
[sweep]
x = [1, 2, 3, 4, 5, 6]
"""


def test_a_study_killed_mid_run_and_resumed_leaves_nothing_anywhere(tmp_path):
    """SIGKILL the whole study (process group) while its runs are in their scratch
    folders, then resume it with TMPDIR at a private folder: the resume removes what the
    killed runs left, finishes every run, and nothing of ours is left in the study folder,
    beside it, or in the temporary directory."""
    spec = tmp_path / "kill.toml"
    spec.write_text(KILL)
    private = tmp_path / "tmpdir"
    private.mkdir()
    out = tmp_path / "study"
    cmd = [sys.executable, "-m", "scanamp", "-q", "study", str(spec), "--out", str(out),
           "--workers", "2"]
    env = _env(TMPDIR=str(private))
    proc = subprocess.Popen(cmd, cwd=tmp_path, env=env, start_new_session=True,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        _wait_for(lambda: len(list(out.glob(".scanamp-scratch-*"))) >= 2, proc,
                  "two runs at work")
    finally:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    left = _ours(tmp_path)
    assert sum(n.startswith("study/.scanamp-scratch-") for n in left) >= 2, left
    res = subprocess.run(cmd, cwd=tmp_path, env=env, capture_output=True, text=True,
                         timeout=300)
    assert res.returncode == 0, res.stderr
    assert len(list((out / "runs").glob("*.json"))) == 6
    assert _ours(tmp_path) == []
    assert sorted(os.listdir(private)) == []


def _seamed_sphere():
    """A sphere cut along its equator into two halves that share no vertex: every vertex
    on the cut has a coincident twin (same position, colour and normal)."""
    import open3d as o3d

    from core.meshes import mesh_arrays

    v, f = mesh_arrays(o3d.geometry.TriangleMesh.create_sphere(1.0, 12))
    top = v[f].mean(axis=1)[:, 2] > 0
    shared = np.intersect1d(f[top], f[~top])
    twin = np.full(len(v), -1)
    twin[shared] = len(v) + np.arange(len(shared))
    f = f.copy()
    g = f[top]
    f[top] = np.where(np.isin(g, shared), twin[g], g)
    v = np.vstack([v, v[shared]])
    colors = 0.5 + 0.5 * v / np.linalg.norm(v, axis=1, keepdims=True)
    return v, f, colors, len(shared)


def test_the_canonical_order_is_invariant_to_any_permutation(tmp_path):
    from core.io.mesh import write_mesh
    from core.meshes import make_mesh, mesh_arrays, sorted_mesh

    v, f, colors, twins = _seamed_sphere()
    assert twins >= 12
    rng = np.random.default_rng(5)
    perm = rng.permutation(len(v))  # new index of each old vertex
    inv = np.argsort(perm)
    f2 = perm[f][rng.permutation(len(f))]
    f2 = np.take_along_axis(f2, (rng.integers(0, 3, len(f2))[:, None] + np.arange(3)) % 3,
                            axis=1)  # each triangle from another corner, winding kept
    a = sorted_mesh(make_mesh(v, f, vertex_colors=colors, compute_normals=False))
    b = sorted_mesh(make_mesh(v[inv], f2, vertex_colors=colors[inv]), recompute_normals=True)
    # normals given as data are carried over exactly
    n = rng.normal(size=v.shape)
    c = sorted_mesh(make_mesh(v, f, vertex_colors=colors, vertex_normals=n))
    d = sorted_mesh(make_mesh(v[inv], f2, vertex_colors=colors[inv], vertex_normals=n[inv]))
    assert np.array_equal(np.asarray(c.vertex_normals), np.asarray(d.vertex_normals))
    for name in ("vertices", "triangles", "vertex_colors", "vertex_normals"):
        assert np.array_equal(np.asarray(getattr(a, name)), np.asarray(getattr(b, name))), name
    pa, pb = write_mesh(tmp_path / "a.ply", a), write_mesh(tmp_path / "b.ply", b)
    assert pa.read_bytes() == pb.read_bytes()
    # the same surface: every triangle's corners, and its normal (so its winding), kept
    va, fa = mesh_arrays(a)

    assert len(fa) == len(f) and len(va) == len(v)
    assert sorted(map(tuple, np.round(np.sort(va[fa].reshape(-1, 9), axis=1), 12))) == \
        sorted(map(tuple, np.round(np.sort(v[f].reshape(-1, 9), axis=1), 12)))
    assert np.allclose(np.sort(np.cross(va[fa[:, 1]] - va[fa[:, 0]],
                                        va[fa[:, 2]] - va[fa[:, 0]]), axis=0),
                       np.sort(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]),
                               axis=0))
