"""Strips run in spawned worker processes give the same points.laz and strip files, byte
for byte, as one process: each worker rebuilds the scene and each leg has its own noise
seed. (A survey not split into strips holds the same points, written in other chunks.)"""

from __future__ import annotations

from scanamp.cli import main

SPEC = """
[scene]
name = "block"
seed = 0

[[objects]]
name = "ground"
shape = "plane"
size = [60.0, 60.0]

[[objects]]
name = "house"
shape = "box"
size = [10.0, 10.0, 8.0]
position = [0.0, 0.0, 4.0]
"""


def test_two_workers_write_the_same_bytes_as_one_process(tmp_path):
    scene = tmp_path / "block.toml"
    scene.write_text(SPEC)
    flags = ["--preset", "riegl-lms-q560", "--platform", "multicopter", "--footprint-samples",
             "1", "--altitude", "50", "--density", "100"]
    assert main(["capture", "lidar", str(scene), *flags, "--per-strip",
                 "--out", str(tmp_path / "a")]) == 0
    assert main(["capture", "lidar", str(scene), *flags, "--workers", "2", "--per-strip",
                 "--out", str(tmp_path / "b")]) == 0
    assert len(list((tmp_path / "b" / "strips").glob("*.laz"))) == 2
    strips = [f"strips/{p.name}" for p in (tmp_path / "a" / "strips").iterdir()]
    for name in ["points.laz", *strips]:
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes()
