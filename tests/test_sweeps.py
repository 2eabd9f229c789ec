"""Sweeps: closed-form volumes, watertightness, frames."""

import numpy as np
import pytest

from core.meshes import make_mesh
from procgen.sweeps import (
    edge_manifold_report,
    extrude,
    frenet_frames,
    mesh_volume,
    revolve,
    sweep,
    transport_frames,
)


def _circle(m, r=1.0):
    t = np.linspace(0, 2 * np.pi, m, endpoint=False)
    return r * np.c_[np.cos(t), np.sin(t)]


@pytest.mark.parametrize("m", [16, 64, 512])
def test_circle_along_line_is_pi_r2_h(m):
    r, h = 0.7, 2.5
    path = np.c_[np.zeros(5), np.zeros(5), np.linspace(0, h, 5)]
    v, f = sweep(_circle(m, r), path)
    polygon = m / 2 * r**2 * np.sin(2 * np.pi / m)
    assert mesh_volume(v, f) == pytest.approx(polygon * h, rel=1e-12)  # exact for the m-gon
    # the inscribed polygon converges to pi r^2 h from below, error ~ (2 pi / m)^2 / 6
    err = 1 - mesh_volume(v, f) / (np.pi * r**2 * h)
    assert 0 < err < (2 * np.pi / m) ** 2 / 6 * 1.01
    assert make_mesh(v, f).is_watertight()


def test_helix_tube_volume_and_watertight():
    s = np.linspace(0, 4 * np.pi, 400)
    path = np.c_[3 * np.cos(s), 3 * np.sin(s), 0.5 * s]
    v, f = sweep(_circle(48, 0.3), path)
    length = 4 * np.pi * np.hypot(3, 0.5)
    area = 24 * 0.09 * np.sin(2 * np.pi / 48)
    assert mesh_volume(v, f) == pytest.approx(area * length, rel=2e-3)
    rep = edge_manifold_report(f)
    assert rep["boundary"] == rep["nonmanifold"] == rep["inconsistent"] == 0
    # open3d's check includes self-intersection (slow): on a coarse helix
    vc, fc = sweep(_circle(8, 0.3), path[::8])
    assert make_mesh(vc, fc).is_watertight()
    v2, f2 = sweep(_circle(48, 0.3), path, frames="frenet")
    assert mesh_volume(v2, f2) == pytest.approx(mesh_volume(v, f), rel=1e-3)


def test_parallel_transport_minimizes_twist():
    s = np.linspace(0, 4 * np.pi, 300)
    path = np.c_[np.cos(s), np.sin(s), 0.3 * s]
    F = transport_frames(path)
    gram = np.einsum("nij,nkj->nik", F, F)
    np.testing.assert_allclose(gram, np.broadcast_to(np.eye(3), gram.shape), atol=1e-9)
    # rotation-minimizing: dN/ds has no component along B
    dN = np.diff(F[:, 1], axis=0)
    assert np.max(np.abs(np.sum(dN * F[:-1, 2], axis=1))) < 1e-3
    with pytest.raises(ValueError, match="Frenet"):
        frenet_frames(np.c_[np.zeros(4), np.zeros(4), np.arange(4.0)])


def test_twist_and_scale_profiles():
    path = np.c_[np.zeros(20), np.zeros(20), np.linspace(0, 1, 20)]
    square = np.array([[1, 1], [-1, 1], [-1, -1], [1, -1]], float) * 0.5
    v, f = sweep(square, path, twist=np.linspace(0, np.pi / 2, 20))
    assert mesh_volume(v, f) < 1.0  # twisted facets cut inside the straight prism
    v, f = sweep(_circle(256), path, scale=np.linspace(1, 0.5, 20))
    want = np.pi / 3 * (1 + 0.5 + 0.25)  # frustum
    assert mesh_volume(v, f) == pytest.approx(want, rel=1e-3)


def test_translational_and_rotational_sweeps():
    v, f = extrude(np.array([[0, 0], [2, 0], [2, 1], [0, 1]], float), 3.0)
    assert mesh_volume(v, f) == pytest.approx(6.0)
    a = np.linspace(-np.pi / 2, np.pi / 2, 200)
    v, f = revolve(np.c_[np.cos(a), np.sin(a)], segments=256)
    assert mesh_volume(v, f) == pytest.approx(4 / 3 * np.pi, rel=1e-3)
    ac = np.linspace(-np.pi / 2, np.pi / 2, 20)
    vc, fc = revolve(np.c_[np.cos(ac), np.sin(ac)], segments=16)
    assert make_mesh(vc, fc).is_watertight()
    v, f = revolve(np.c_[np.cos(a), np.sin(a)], segments=128, angle=np.pi)
    assert mesh_volume(v, f) == pytest.approx(2 / 3 * np.pi, rel=1e-3)
    assert edge_manifold_report(f)["boundary"] == 0
    # torus by revolving an offset circle: 2 pi^2 R r^2
    v, f = revolve(np.vstack([_circle(128, 0.5) + [2, 0], [[2.5, 0]]]), segments=256)
    assert mesh_volume(v, f) == pytest.approx(2 * np.pi**2 * 2 * 0.25, rel=2e-3)


def test_open_ribbon_and_bad_input():
    path = np.c_[np.zeros(3), np.zeros(3), np.arange(3.0)]
    v, f = sweep(np.array([[0, 0], [1, 0]], float), path, closed_profile=False)
    assert edge_manifold_report(f)["boundary"] > 0
    with pytest.raises(ValueError, match="frames"):
        sweep(_circle(8), path, frames="bishop")
    with pytest.raises(ValueError, match="path"):
        sweep(_circle(8), np.zeros((3, 2)))
