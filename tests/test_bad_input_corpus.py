"""The bad-input corpus (issue 15): every subcommand, fed what users really feed it.

Each case runs ``scanamp`` in-process inside a sentinel tree of inputs and asserts:
exit status 2; exactly one line on stderr, ``error: ...``, naming the file and/or field
at fault; no traceback; nothing left behind and every file that was there before
byte-identical after (checksums of the whole tree).

``python tests/test_bad_input_corpus.py`` prints the table (case, exit code, message).
"""

from __future__ import annotations

import hashlib
import json
import os
import sys
from pathlib import Path

import numpy as np
import pytest

from scanamp.cli import main

GRAMMAR = "axiom: F\nF -> F[+F]F\n"


def _ply_bytes(vertices, faces) -> bytes:
    v = np.asarray(vertices, "<f4")
    head = (f"ply\nformat binary_little_endian 1.0\nelement vertex {len(v)}\n"
            "property float x\nproperty float y\nproperty float z\n"
            f"element face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n")
    body = v.tobytes() + b"".join(np.uint8(3).tobytes() + np.asarray(f, "<i4").tobytes()
                                  for f in faces)
    return head.encode() + body


def _make_world(root: Path) -> None:
    """The sentinel tree: good and bad inputs, and things that are the user's."""
    tet = [[0, 0, 0], [0.1, 0, 0], [0, 0.1, 0], [0, 0, 0.1]]
    faces = [[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]]
    (root / "good.ply").write_bytes(_ply_bytes(tet, faces))
    (root / "garbage.ply").write_bytes(b"this is not a mesh")
    (root / "truncated.ply").write_bytes(_ply_bytes(tet, faces)[:-20])
    (root / "nan.ply").write_bytes(_ply_bytes([[np.nan, 0, 0], *tet[1:]], faces))
    (root / "nofaces.ply").write_bytes(_ply_bytes(tet, []))
    (root / "notes.txt").write_text("the user's notes")
    (root / "mine").mkdir()
    (root / "mine" / "thesis.tex").write_text("years of work")
    (root / "picture.png").write_bytes(b"\x89PNG\r\n\x1a\n" + b"\x00" * 40)  # truncated PNG
    (root / "photo.jpg").write_bytes(b"\xff\xd8\xff\xe0" + b"\x00" * 30)  # truncated JPEG
    (root / "broken.toml").write_text("[scene\nname = ")
    (root / "broken.json").write_text("{\"a\": ")
    (root / "g.lsys").write_text(GRAMMAR)
    (root / "unbalanced.lsys").write_text("axiom: F\nF -> F[+F\n")
    (root / "unknown.lsys").write_text("axiom: F\nF -> F[+Q]\n")
    (root / "arity.lsys").write_text("axiom: A(1)\nA(x) -> A(x, 2)\n")
    (root / "explosive.lsys").write_text("n: 40\naxiom: F\nF -> FFFFFFFF\n")
    (root / "inject.lsys").write_text("axiom: F(__import__('os').system('echo x'))\n")
    (root / "empty_sweep.toml").write_text(
        "name = \"s\"\nkind = \"laser\"\nscene = \"object\"\n[sweep]\n")
    (root / "images").mkdir()
    (root / "images" / "a.jpg").write_bytes(b"\xff\xd8\xff\xe0" + b"\x00" * 30)
    (root / "images" / "b.png").write_bytes(b"\x89PNG\r\n\x1a\n")
    cap = root / "cap"
    cap.mkdir()
    (cap / "capture.json").write_text(json.dumps({
        "format": "scanamp.capture/1", "kind": "laser", "frames": [
            {"image": "images/scan_0000.png", "angle_deg": 0.0}]}))
    bad = root / "badcap"
    bad.mkdir()
    (bad / "capture.json").write_text("{\"format\": ")
    assert main(["-q", "scene", "primitives", "--out", str(root / "sc")]) == 0
    assert main(["-q", "procgen", "fractal", "koch", "--width", "32", "--height", "24",
                 "--level", "1", "--out", str(root / "existing.png")]) == 0


# (id, argv with {root} for the tree, substrings the message must hold)
CASES: list[tuple[str, list[str], tuple[str, ...]]] = [
    # -- outputs that would destroy something
    ("scene onto a file", ["scene", "object", "--out", "{root}/notes.txt"], ("notes.txt",)),
    ("scene into a user's folder", ["scene", "object", "--out", "{root}/mine"], ("mine",)),
    ("capture over its input", ["capture", "sfm", "{root}/sc", "--out", "{root}/sc"],
     ("sc", "is the input")),
    ("capture inside its input", ["capture", "sfm", "{root}/sc", "--out", "{root}/sc/x"],
     ("inside the input",)),
    ("capture containing its input", ["capture", "laser", "{root}/sc", "--out", "{root}"],
     ("contains the input",)),
    ("another command's folder", ["simulate", "boids", "torus", "--out", "{root}/sc",
                                  "--overwrite"], ("sc", "scanamp scene")),
    ("render onto an existing PNG", ["render", "{root}/sc", "--out", "{root}/existing.png"],
     ("existing.png", "--overwrite")),
    ("fractal onto an existing PNG", ["procgen", "fractal", "koch", "--out",
                                      "{root}/existing.png"], ("existing.png",)),
    ("grow onto an existing mesh", ["grow", "{root}/g.lsys", "--out", "{root}/good.ply"],
     ("good.ply",)),
    ("evaluate --json onto notes", ["evaluate", "{root}/good.ply", "--reference",
                                    "{root}/good.ply", "--json", "{root}/notes.txt"],
     ("notes.txt",)),
    ("amplify into a user's folder", ["amplify", "{root}/good.ply", "--recipe", "snow",
                                      "--out", "{root}/mine"], ("mine",)),
    ("study into a user's folder", ["study", "laser-angle", "--out", "{root}/mine"],
     ("mine",)),
    ("demo into a user's folder", ["demo", "--out", "{root}/mine"], ("mine",)),
    ("demo onto a file", ["demo", "--out", "{root}/notes.txt"], ("notes.txt",)),
    ("reconstruct over its capture", ["reconstruct", "laser", "{root}/cap", "--out",
                                      "{root}/cap"], ("cap", "is the input")),
    ("calibrate onto notes", ["calibrate", "camera", "{root}/images", "--board",
                              "charuco:6x5:0.025:0.018", "--out", "{root}/notes.txt"],
     ("notes.txt",)),
    ("particles into the scene", ["simulate", "particles", "fire", "--out", "{root}/sc",
                                  "--overwrite"], ("sc",)),
    # -- corrupt, truncated, NaN, empty meshes
    ("evaluate a garbage PLY", ["evaluate", "{root}/garbage.ply", "--reference",
                                "{root}/good.ply"], ("garbage.ply",)),
    ("evaluate a truncated PLY", ["evaluate", "{root}/truncated.ply", "--reference",
                                  "{root}/good.ply"], ("truncated.ply", "truncated")),
    ("evaluate a NaN PLY", ["evaluate", "{root}/nan.ply", "--reference", "{root}/good.ply"],
     ("nan.ply",)),
    ("evaluate against a garbage reference", ["evaluate", "{root}/good.ply", "--reference",
                                              "{root}/garbage.ply"], ("garbage.ply",)),
    ("evaluate a missing file", ["evaluate", "{root}/missing.ply", "--reference",
                                 "{root}/good.ply"], ("missing.ply",)),
    ("amplify a garbage PLY", ["amplify", "{root}/garbage.ply", "--recipe", "snow",
                               "--out", "{root}/o"], ("garbage.ply",)),
    ("amplify a truncated PLY", ["amplify", "{root}/truncated.ply", "--recipe", "snow",
                                 "--out", "{root}/o"], ("truncated.ply",)),
    ("amplify a NaN PLY", ["amplify", "{root}/nan.ply", "--recipe", "snow", "--out",
                           "{root}/o"], ("nan.ply",)),
    ("amplify a mesh with no faces", ["amplify", "{root}/nofaces.ply", "--recipe", "snow",
                                      "--out", "{root}/o"], ("nofaces.ply",)),
    ("amplify an unknown recipe", ["amplify", "{root}/good.ply", "--recipe", "nosuch",
                                   "--out", "{root}/o"], ("nosuch",)),
    ("amplify a malformed recipe", ["amplify", "{root}/good.ply", "--recipe",
                                    "{root}/broken.toml", "--out", "{root}/o"],
     ("broken.toml",)),
    ("particles with a garbage mesh", ["simulate", "particles", "fire", "--mesh",
                                       "{root}/garbage.ply", "--out", "{root}/o"],
     ("garbage.ply",)),
    ("hypertexture of a garbage mesh", ["procgen", "hypertexture", "mesh", "--mesh",
                                        "{root}/garbage.ply", "--out", "{root}/o.ply"],
     ("garbage.ply",)),
    # -- images
    ("calibrate from corrupt images", ["calibrate", "camera", "{root}/images", "--board",
                                       "charuco:6x5:0.025:0.018", "--out", "{root}/c.yaml"],
     ("images",)),
    ("calibrate with a bad board", ["calibrate", "camera", "{root}/images", "--board",
                                    "hexagon:1", "--out", "{root}/c.yaml"], ("board",)),
    ("stereo pair of truncated images", ["reconstruct", "stereo", "--left",
                                         "{root}/picture.png", "--right", "{root}/photo.jpg",
                                         "--calibration", "{root}/broken.json", "--out",
                                         "{root}/o"], ("{root}/",)),
    ("sfm on corrupt photos", ["reconstruct", "sfm", "{root}/images", "--out", "{root}/o"],
     ("images",)),
    ("hypertexture without --mesh", ["procgen", "hypertexture", "mesh", "--out",
                                     "{root}/o.ply"], ("--mesh",)),
    # -- malformed TOML and JSON, unknown names
    ("scene from malformed TOML", ["scene", "{root}/broken.toml", "--out", "{root}/o"],
     ("broken.toml",)),
    ("render malformed TOML", ["render", "{root}/broken.toml", "--out", "{root}/o.png"],
     ("broken.toml",)),
    ("unknown scene", ["scene", "atlantis", "--out", "{root}/o"], ("atlantis",)),
    ("capture an unknown scene", ["capture", "sfm", "atlantis", "--out", "{root}/o"],
     ("atlantis",)),
    ("capture with a malformed config", ["capture", "laser", "{root}/sc", "--config",
                                         "{root}/broken.toml", "--out", "{root}/o"],
     ("broken.toml",)),
    ("reconstruct with a malformed config", ["reconstruct", "laser", "{root}/cap",
                                             "--config", "{root}/broken.toml", "--out",
                                             "{root}/o"], ("broken.toml",)),
    ("reconstruct a malformed capture.json", ["reconstruct", "laser", "{root}/badcap",
                                              "--out", "{root}/o"], ("capture.json",)),
    ("reconstruct a capture with missing images", ["reconstruct", "laser", "{root}/cap",
                                                   "--out", "{root}/o"], ("scan_0000.png",)),
    ("reconstruct a folder without capture", ["reconstruct", "structured-light",
                                              "{root}/mine", "--out", "{root}/o"],
     ("mine",)),
    ("stereo with a malformed calibration", ["reconstruct", "stereo", "--left",
                                             "{root}/existing.png", "--right",
                                             "{root}/existing.png", "--calibration",
                                             "{root}/broken.json", "--out", "{root}/o"],
     ("broken.json",)),
    ("particles from malformed TOML", ["simulate", "particles", "{root}/broken.toml",
                                       "--out", "{root}/o"], ("broken.toml",)),
    ("boids: unknown recipe", ["simulate", "boids", "nosuch", "--out", "{root}/o"],
     ("nosuch",)),
    ("cloth: unknown recipe", ["simulate", "cloth", "nosuch", "--out", "{root}/o"],
     ("nosuch",)),
    ("study from malformed TOML", ["study", "{root}/broken.toml", "--out", "{root}/o"],
     ("broken.toml",)),
    ("study: unknown name", ["study", "nosuch", "--out", "{root}/o"], ("nosuch",)),
    ("study with an empty sweep", ["study", "{root}/empty_sweep.toml", "--out", "{root}/o"],
     ("empty_sweep.toml",)),
    ("study: unreachable scheduler", ["study", "laser-angle", "--out", "{root}/o",
                                      "--scheduler", "tcp://127.0.0.1:9", "--timeout", "0.5"],
     ("127.0.0.1:9",)),
    ("terrain: unknown method", ["procgen", "terrain", "--method", "nosuch", "--out",
                                 "{root}/o.ply"], ("nosuch",)),
    ("demo: unknown method", ["demo", "--methods", "laser,teleport", "--out", "{root}/o"],
     ("teleport",)),
    # -- NaN, inf, negative and absurd sizes
    ("fractal of negative width", ["procgen", "fractal", "koch", "--width", "-5", "--out",
                                   "{root}/o.png"], ("width",)),
    ("fractal of absurd size", ["procgen", "fractal", "mandelbrot", "--width", "1000000",
                                "--height", "1000000", "--out", "{root}/o.png"], ("width",)),
    ("fractal zoom NaN", ["procgen", "fractal", "mandelbrot", "--zoom", "nan", "--out",
                          "{root}/o.png"], ("zoom",)),
    ("terrain size not 2^n+1", ["procgen", "terrain", "--size", "100", "--out",
                                "{root}/o.ply"], ("size",)),
    ("terrain extent inf", ["procgen", "terrain", "--extent", "inf", "--out", "{root}/o.ply"],
     ("extent",)),
    ("terrain hurst negative", ["procgen", "terrain", "--hurst", "-1", "--out",
                                "{root}/o.ply"], ("hurst",)),
    ("render size 0x0", ["render", "{root}/sc", "--size", "0x0", "--out", "{root}/o.png"],
     ("size",)),
    ("render size garbage", ["render", "{root}/sc", "--size", "big", "--out", "{root}/o.png"],
     ("--size",)),
    ("render fov NaN", ["render", "{root}/sc", "--fov", "nan", "--out", "{root}/o.png"],
     ("fov",)),
    ("render without .png", ["render", "{root}/sc", "--out", "{root}/o.txt"], ("--out",)),
    ("capture with negative views", ["capture", "sfm", "{root}/sc", "--views", "-3", "--out",
                                     "{root}/o"], ("views",)),
    ("boids with negative count", ["simulate", "boids", "torus", "--n", "-5", "--out",
                                   "{root}/o"], ("n",)),
    ("particles with negative frames", ["simulate", "particles", "fire", "--frames", "-2",
                                        "--out", "{root}/o"], ("frames",)),
    ("evaluate tau negative", ["evaluate", "{root}/good.ply", "--reference", "{root}/good.ply",
                               "--tau", "-1"], ("tau",)),
    ("evaluate tau NaN", ["evaluate", "{root}/good.ply", "--reference", "{root}/good.ply",
                          "--tau", "nan"], ("tau",)),
    ("reconstruct laser threshold negative", ["reconstruct", "laser", "{root}/cap",
                                              "--threshold", "-4", "--out", "{root}/o"],
     ("threshold",)),
    ("study with zero workers", ["study", "laser-angle", "--workers", "0", "--out",
                                 "{root}/o"], ("workers",)),
    # -- grammars
    ("grow: unbalanced bracket", ["grow", "{root}/unbalanced.lsys", "--out", "{root}/o.ply"],
     ("unbalanced.lsys", "line 2, column 7")),
    ("grow: unknown module", ["grow", "{root}/unknown.lsys", "--out", "{root}/o.ply"],
     ("unknown.lsys", "line 2", "'Q'")),
    ("grow: parameter count", ["grow", "{root}/arity.lsys", "--out", "{root}/o.ply"],
     ("arity.lsys", "line 2")),
    ("grow: explosive grammar", ["grow", "{root}/explosive.lsys", "--out", "{root}/o.ply"],
     ("explosive.lsys",)),
    ("grow: injected expression", ["grow", "{root}/inject.lsys", "--out", "{root}/o.ply"],
     ("inject.lsys",)),
    ("grow: unknown example", ["grow", "nosuch_example", "--out", "{root}/o.ply"],
     ("nosuch_example",)),
    ("grow: wrong suffix", ["grow", "{root}/g.lsys", "--out", "{root}/o.txt"], ("--out",)),
]


def _tree_state(root: Path) -> dict[str, str]:
    state = {}
    for dirpath, dirnames, filenames in os.walk(root):
        for name in dirnames:
            state[os.path.relpath(os.path.join(dirpath, name), root) + "/"] = "dir"
        for name in filenames:
            p = os.path.join(dirpath, name)
            state[os.path.relpath(p, root)] = hashlib.sha256(Path(p).read_bytes()).hexdigest()
    return state


@pytest.fixture(scope="module")
def world(tmp_path_factory):
    root = tmp_path_factory.mktemp("corpus")
    _make_world(root)
    return root, _tree_state(root)


def run_case(root: Path, argv: list[str], capsys) -> tuple[int, str]:
    args = [a.replace("{root}", str(root)) for a in argv]
    capsys.readouterr()
    try:
        code = main(args)
    except SystemExit as exc:  # argparse: a flag's value is not among its choices
        code = exc.code
    return code, capsys.readouterr().err


def test_the_corpus_is_big_enough():
    assert len(CASES) >= 60
    assert len({c[0] for c in CASES}) == len(CASES)


@pytest.mark.parametrize("name, argv, needs", CASES, ids=[c[0] for c in CASES])
def test_bad_input(world, capsys, name, argv, needs):
    root, before = world
    code, err = run_case(root, argv, capsys)
    lines = err.strip("\n").split("\n")
    assert code == 2, err
    assert len(lines) == 1 and lines[0].startswith("error: "), err
    assert "Traceback" not in err and "scanamp-tmp-" not in err
    for needle in needs:
        assert needle.replace("{root}", str(root)) in lines[0], (needle, err)
    assert _tree_state(root) == before  # nothing left behind, nothing changed


if __name__ == "__main__":  # the table for the closing note
    import tempfile

    class _Cap:
        def readouterr(self):
            out = sys.stderr.getvalue()
            sys.stderr.seek(0)
            sys.stderr.truncate()
            return type("R", (), {"err": out, "out": ""})()

    import io

    root = Path(tempfile.mkdtemp())
    real = sys.stderr
    sys.stderr = io.StringIO()
    _make_world(root)
    rows = []
    cap = _Cap()
    for name, argv, _ in CASES:
        code, err = run_case(root, argv, cap)
        rows.append((name, code, err.strip().replace(str(root), "ROOT")))
    sys.stderr = real
    print("| case | exit | message |\n|---|---|---|")
    for name, code, msg in rows:
        print(f"| {name} | {code} | `{msg}` |")
