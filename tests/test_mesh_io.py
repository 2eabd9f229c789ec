"""core.io.mesh: the labelled-mesh PLY (colour and part label per vertex)."""

import numpy as np
import pytest

from core.validate import InputError


def test_labeled_mesh_round_trip_and_readers_agree(tmp_path):
    import open3d as o3d

    from core.io.mesh import read_labeled_mesh, write_labeled_mesh

    rng = np.random.default_rng(0)
    v, f = rng.normal(size=(40, 3)), rng.integers(0, 40, (60, 3))
    c, lab = rng.random((40, 3)), rng.integers(0, 4, 40)
    p = write_labeled_mesh(tmp_path / "m.ply", v, f, colors=c, labels=lab,
                           names={0: "ground", 3: "leaf"})
    m = read_labeled_mesh(p)
    assert np.array_equal(m["vertices"], v) and np.array_equal(m["triangles"], f)
    assert np.array_equal(m["labels"], lab) and m["names"] == {0: "ground", 3: "leaf"}
    assert np.array_equal(m["colors"], np.round(c * 255).astype(np.uint8))
    om = o3d.io.read_triangle_mesh(str(p))  # another reader sees the same mesh and colours
    assert np.array_equal(np.asarray(om.triangles), f)
    assert np.allclose(np.asarray(om.vertex_colors) * 255, m["colors"], atol=1e-3)
    (tmp_path / "t.ply").write_bytes(p.read_bytes()[:300])
    with pytest.raises(InputError, match="t.ply.*truncated"):
        read_labeled_mesh(tmp_path / "t.ply")


def test_native_output_captures_descriptors_without_open3d():
    import os

    from core.io.mesh import native_output

    said = []
    with native_output(said, fds=(1, 2), open3d=False):
        os.write(1, b"progress 50%\n")
        os.write(2, b"a warning\n")
    assert said == ["progress 50%", "a warning"]
