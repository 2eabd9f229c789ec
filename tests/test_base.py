import numpy as np
import pytest

from procgen.files import atomic_dir, read_toml, require
from procgen.meshes import (
    from_pymeshlab,
    from_pyvista,
    make_mesh,
    mesh_arrays,
    to_pymeshlab,
    to_pyvista,
)
from procgen.validate import InputError, check_array, check_choice, check_range


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


def test_atomic_dir_keeps_old_on_failure(tmp_path):
    out = tmp_path / "out"
    with atomic_dir(out) as d:
        (d / "a").write_text("1")
    with pytest.raises(RuntimeError):
        with atomic_dir(out) as d:
            (d / "b").write_text("2")
            raise RuntimeError("boom")
    assert sorted(p.name for p in out.iterdir()) == ["a"]
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

    from procgen.meshes import is_closed

    box = o3d.geometry.TriangleMesh.create_box()
    assert is_closed(box)
    f = np.asarray(box.triangles)
    assert not is_closed(f[1:])  # a hole
    flipped = f.copy()
    flipped[0] = flipped[0, ::-1]
    assert not is_closed(flipped)  # inconsistent orientation
