import os
import subprocess
import sys

import numpy as np
import pytest

from core.files import atomic_dir, read_toml, require
from core.meshes import (
    from_pymeshlab,
    from_pyvista,
    make_mesh,
    mesh_arrays,
    to_pymeshlab,
    to_pyvista,
)
from core.validate import InputError, check_array, check_choice, check_int, check_range


def test_check_array_names_shape():
    with pytest.raises(ValueError, match=r"points: expected shape \(n, 3\), got \(5, 2\)"):
        check_array(np.zeros((5, 2)), "points", shape=(None, 3))
    with pytest.raises(ValueError, match="finite"):
        check_array([[np.nan, 0, 0]], "points", shape=(None, 3))


def test_check_choice_lists_all():
    with pytest.raises(ValueError, match="'a', 'b'.*got 'c'"):
        check_choice("c", "mode", {"b", "a"})


def test_check_range():
    with pytest.raises(ValueError, match=r"hurst: expected a value in \(0, 1\)"):
        check_range(1.0, "hurst", 0, 1, lo_open=True, hi_open=True)


def test_check_int_accepts_integral_numbers_only():
    assert check_int(3, "n") == 3 and check_int(3.0, "n") == 3
    assert check_int(np.int64(7), "n") == 7 and type(check_int(np.int64(7), "n")) is int
    assert check_int(0, "k", 0) == 0
    for bad in (2.5, True, "3", float("nan"), float("inf"), None, 0):
        with pytest.raises(ValueError, match=r"^n: expected a positive integer, got"):
            check_int(bad, "n")
    with pytest.raises(ValueError, match=r"^size: expected an integer >= 3, got 2$"):
        check_int(2, "size", 3)


def test_atomic_dir_keeps_old_on_failure(tmp_path):
    out = tmp_path / "out"
    with atomic_dir(out) as d:
        (d / "a").write_text("1")
    with pytest.raises(RuntimeError):
        with atomic_dir(out) as d:
            (d / "b").write_text("2")
            raise RuntimeError("boom")
    assert sorted(p.name for p in out.iterdir()) == [".scanamp.json", "a"]
    assert [p.name for p in tmp_path.iterdir()] == ["out"]


def test_toml_errors_name_file_and_field(tmp_path):
    p = tmp_path / "x.toml"
    p.write_text("a = [1,")
    with pytest.raises(InputError, match="x.toml: malformed TOML"):
        read_toml(p)
    p.write_text("a = 'text'")
    with pytest.raises(InputError, match=r"x.toml: obj.a: expected a number"):
        require(read_toml(p), "a", float, path=p, prefix="obj")


def test_mesh_conversions_round_trip():
    import open3d as o3d

    box = o3d.geometry.TriangleMesh.create_box(1, 2, 3)
    v, f = mesh_arrays(box)
    for back in (from_pymeshlab(to_pymeshlab(box)), from_pyvista(to_pyvista(box))):
        v2, f2 = mesh_arrays(back)
        np.testing.assert_allclose(v2, v)
        np.testing.assert_array_equal(f2, f)
    with pytest.raises(ValueError, match="triangles"):
        make_mesh(v, f + 100)


def test_is_closed():
    import open3d as o3d

    from core.meshes import is_closed

    box = o3d.geometry.TriangleMesh.create_box()
    assert is_closed(box)
    f = np.asarray(box.triangles)
    assert not is_closed(f[1:])  # a hole
    flipped = f.copy()
    flipped[0] = flipped[0, ::-1]
    assert not is_closed(flipped)  # inconsistent orientation


def test_atomic_outputs_get_the_usual_permissions(tmp_path):
    import os
    import stat

    from core.files import atomic_file, write_json

    old = os.umask(0o022)
    try:
        write_json(tmp_path / "r.json", {"a": 1})
        with atomic_file(tmp_path / "b.bin") as t:
            t.write_bytes(b"x")
        with atomic_dir(tmp_path / "d") as d:
            (d / "f.txt").write_text("x")
        os.umask(0o027)
        with atomic_file(tmp_path / "c.bin") as t:
            t.write_bytes(b"x")
    finally:
        os.umask(old)
    mode = lambda p: stat.S_IMODE((tmp_path / p).stat().st_mode)  # noqa: E731
    assert mode("r.json") == 0o644 and mode("b.bin") == 0o644
    assert mode("d") == 0o755
    assert mode("c.bin") == 0o640  # follows the umask, like open()


def test_write_points_empty_cloud_is_a_valid_ply(tmp_path):
    import numpy as np
    import open3d as o3d
    import pytest

    from core.io.mesh import write_points

    write_points(tmp_path / "e.ply", np.zeros((0, 3)), colors=np.zeros((0, 3)))
    assert len(o3d.io.read_point_cloud(str(tmp_path / "e.ply")).points) == 0
    head = (tmp_path / "e.ply").read_bytes().decode("ascii")
    assert "element vertex 0" in head and "property uchar red" in head
    assert head.endswith("end_header\n")
    # the same header as a non-empty cloud written by open3d
    write_points(tmp_path / "one.ply", np.zeros((1, 3)), colors=np.zeros((1, 3)))
    props = [ln for ln in (tmp_path / "one.ply").read_bytes().split(b"end_header")[0]
             .decode().splitlines() if ln.startswith("property")]
    assert props == [ln for ln in head.splitlines() if ln.startswith("property")]
    with pytest.raises(ValueError, match="ply"):
        write_points(tmp_path / "e.xyz", np.zeros((0, 3)))


_REALLOC = """
import resource, numpy as np
import core
a = np.ones(100 << 17); del a          # 100 MB, touched, freed
f0 = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
a = np.ones(100 << 17)
print(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - f0)
"""


@pytest.mark.skipif(sys.platform != "linux", reason="glibc's malloc")
def test_large_freed_blocks_are_reused_unless_the_environment_says_otherwise():
    # a block given back to the system faults in again: 100 MB is 25 600 pages of 4 KB,
    # or 50 huge pages of 2 MB
    env = {k: v for k, v in os.environ.items() if not k.startswith(("MALLOC_", "GLIBC_"))}
    run = [sys.executable, "-c", _REALLOC]
    ours = int(subprocess.run(run, env=env, capture_output=True, text=True, check=True).stdout)
    theirs = int(subprocess.run(run, env={**env, "MALLOC_TRIM_THRESHOLD_": "65536"},
                                capture_output=True, text=True, check=True).stdout)
    assert theirs >= 50, theirs
    assert ours * 10 < theirs, (ours, theirs)
