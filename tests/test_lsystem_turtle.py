"""Turtle conventions, tropism, polygons, widths, and watertight tube meshes."""

import numpy as np
import pytest

from procgen.lsystem import (
    INITIAL_FRAME,
    derive,
    interpret,
    load_grammar,
    parse_grammar,
    to_mesh,
    tube_arrays,
)
from procgen.sweeps import edge_manifold_report, mesh_volume


def _run(text, **kw):
    g = parse_grammar(text)
    return interpret(derive(g), g, **kw)


def test_initial_frame_is_right_handed_and_z_up():
    H, L, U = INITIAL_FRAME
    np.testing.assert_allclose(np.cross(H, L), U)
    np.testing.assert_allclose(H, [0, 0, 1])
    r = _run("axiom: F")
    np.testing.assert_allclose(r.ends[0], [0, 0, 1])
    np.testing.assert_allclose(r.frames[0], INITIAL_FRAME)


@pytest.mark.parametrize("sym, direction", [
    ("+", [-1, 0, 0]),   # turn left: toward L = -X
    ("-", [1, 0, 0]),
    ("&", [0, 1, 0]),    # pitch down: toward -U = +Y
    ("^", [0, -1, 0]),
    ("|", [0, 0, -1]),
])
def test_rotation_symbols(sym, direction):
    r = _run(f"angle: 90\naxiom: {sym}F")
    np.testing.assert_allclose(r.ends[0], direction, atol=1e-12)


def test_roll_and_parametric_angles():
    # roll 90 about H (right-handed: L -> U), then turn left: goes toward the old U = -Y
    r = _run("angle: 90\naxiom: \\+F")
    np.testing.assert_allclose(r.ends[0], [0, -1, 0], atol=1e-12)
    r = _run("angle: 10\naxiom: +(30)F(2)")
    np.testing.assert_allclose(r.ends[0], 2 * np.array([-np.sin(np.pi / 6), 0,
                                                        np.cos(np.pi / 6)]), atol=1e-12)


def test_frames_stay_orthonormal():
    g = load_grammar("parametric_tree")
    r = interpret(derive(g, 6), g)
    F = r.frames
    gram = np.einsum("nij,nkj->nik", F, F)
    np.testing.assert_allclose(gram, np.broadcast_to(np.eye(3), gram.shape), atol=1e-9)
    np.testing.assert_allclose(np.linalg.det(F), 1.0, atol=1e-9)


def test_brackets_restore_state_and_parents():
    r = _run("angle: 90\naxiom: F[+F]F")
    np.testing.assert_allclose(r.starts[2], [0, 0, 1])
    np.testing.assert_allclose(r.ends[2], [0, 0, 2])
    assert list(r.parents) == [-1, 0, 0]
    r = _run("axiom: FfF")
    assert list(r.parents) == [-1, -1]
    np.testing.assert_allclose(r.starts[1], [0, 0, 2])


def test_widths_and_colors():
    r = _run("width_factor: 0.5\naxiom: !(0.4)F!F'F'(7)F")
    np.testing.assert_allclose(r.widths, [0.4, 0.2, 0.2, 0.2])
    assert list(r.colors) == [0, 0, 1, 7]


def test_tropism_bends_toward_t():
    up = _run("axiom: FFFFFFFFFF\ntropism: 1, 0, 0, 0.2")
    assert up.ends[-1][0] > 1.0  # bent toward +X
    plain = _run("axiom: FFFFFFFFFF")
    np.testing.assert_allclose(plain.ends[-1], [0, 0, 10])
    # the first step is straight, the second turned by e |H x T| = 0.2 rad
    d = up.ends[1] - up.starts[1]
    assert np.degrees(np.arccos(d[2])) == pytest.approx(np.degrees(0.2), abs=1e-9)


def test_polygons_from_braces():
    r = _run("angle: 90\naxiom: {.f.+f.+f.}")
    assert len(r) == 0
    assert np.unique(r.polygon_ids).size == 1
    mesh = to_mesh(r)
    assert len(mesh.triangles) == 2
    area = mesh.get_surface_area()
    assert area == pytest.approx(1.0)


def test_level_symbol():
    r = _run("angle: 45\naxiom: &/$F")
    H, L, U = r.frames[0]
    assert abs(L[2]) < 1e-12 and np.dot(np.cross(H, L), U) > 0.999


def test_unbranched_tube_is_watertight_by_open3d():
    g = parse_grammar("angle: 30\nwidth: 0.3\naxiom: F+F+F&F^F/F-F!F!F")
    r = interpret(derive(g), g)
    mesh = to_mesh(r, sides=12)
    assert mesh.is_watertight()
    v, f = tube_arrays(r, sides=12)
    assert mesh_volume(v, f) > 0


def test_straight_tube_volume_is_a_frustum_stack():
    # !(w) taper: radii 0.5 -> 0.25 over the second segment
    g = parse_grammar("width: 1\naxiom: F!(0.5)F")
    v, f = tube_arrays(interpret(derive(g), g), sides=256)
    want = np.pi * 0.25 + np.pi / 3 * (0.25 + 0.125 + 0.0625)
    assert mesh_volume(v, f) == pytest.approx(want, rel=1e-3)


@pytest.mark.parametrize("name", ["abop_1_24a", "abop_1_24f", "parametric_tree", "dragon"])
def test_plant_tubes_are_closed_oriented_manifolds(name):
    g = load_grammar(name)
    r = interpret(derive(g, min(g.n, 4)), g)
    v, f = tube_arrays(r, sides=6)
    rep = edge_manifold_report(f)
    assert rep["boundary"] == rep["nonmanifold"] == rep["inconsistent"] == 0


@pytest.mark.parametrize("suffix", [".ply", ".obj", ".gltf"])
def test_mesh_files_round_trip(tmp_path, suffix):
    from core.io.mesh import read_mesh, write_mesh

    g = load_grammar("abop_1_24a")
    mesh = to_mesh(interpret(derive(g, 2), g), sides=5)
    write_mesh(tmp_path / f"p{suffix}", mesh)
    back = read_mesh(tmp_path / f"p{suffix}")
    assert back.get_surface_area() == pytest.approx(mesh.get_surface_area(), rel=1e-5)
