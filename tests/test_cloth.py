import logging
import math

import numpy as np
import open3d as o3d
import pytest

from simulate.cloth import Cloth, ClothSpec, grid_cloth
from simulate.colliders import MeshCollider
from simulate.collisions import ContactParams
from simulate.forces import ForceSet, Gravity, Wind


def test_grid_topology():
    x, tris, springs = grid_cloth(ClothSpec(nx=4, ny=3, spacing=0.1))
    assert x.shape == (12, 3) and tris.shape == (2 * 3 * 2, 3)
    assert len(springs["stretch"]) == 3 * 3 + 4 * 2
    assert len(springs["shear"]) == 2 * 3 * 2
    assert len(springs["bend"]) == 2 * 3 + 4 * 1
    d = np.linalg.norm(x[springs["shear"][:, 1]] - x[springs["shear"][:, 0]], axis=1)
    np.testing.assert_allclose(d, 0.1 * math.sqrt(2))


def test_hanging_cloth_pins_and_strain_limit():
    nx = 10
    spec = ClothSpec(nx=nx, ny=10, spacing=0.05, origin=(0, 0, 1), axis_v=(0, 0, -1),
                     k_stretch=20.0, k_shear=5.0, k_bend=1.0, pinned=(0, nx - 1),
                     max_strain=0.1, mass=0.5)
    cloth = Cloth(spec, ForceSet([Gravity(), Wind((0, 1.0, 0), 0.01)]))
    pinned0 = cloth.x[[0, nx - 1]].copy()
    for _ in range(40):
        cloth.advance(1 / 24, 8)
    np.testing.assert_array_equal(cloth.x[[0, nx - 1]], pinned0)
    # soft springs would sag far more; Provot's limit holds every stretch spring to 10 %
    assert cloth.stretch().max() <= 1.1 * 1.01  # Gauss-Seidel passes: approximate
    free = Cloth(ClothSpec(**{**spec.__dict__, "max_strain": None}), ForceSet([Gravity()]))
    for _ in range(40):
        free.advance(1 / 24, 8)
    assert free.stretch().max() > 1.2


def test_drape_over_table_stays_outside_and_settles():
    table = o3d.geometry.TriangleMesh.create_box(0.5, 0.5, 0.3)
    table.translate((-0.25, -0.25, 0.0))  # top at z = 0.3
    col = MeshCollider(table)
    spec = ClothSpec(nx=14, ny=14, spacing=0.07, origin=(-0.455, -0.455, 0.4), mass=0.3)
    cloth = Cloth(spec, ForceSet([Gravity()]), collider=col,
                  contact=ContactParams(restitution=0.0, friction=1.0, rest_speed=0.05))
    substeps = int(np.ceil(1 / 24 / cloth.stable_step())) + 1
    for _ in range(24):
        cloth.advance(1 / 24, substeps)
    sd = col.signed_distance(cloth.x)
    assert sd.min() > -1e-4  # nothing inside the table
    centre = cloth.x[[6 + 14 * 6, 7 + 14 * 7]].mean(axis=0)
    # on the top (linear bend springs resist the fold at the edges: it tents a little)
    assert 0.3 <= centre[2] < 0.36
    assert cloth.x[:, 2].min() < 0.2  # the corners hang down
    assert cloth.energy()["kinetic"] < 0.05


def test_stable_step_and_warning(caplog):
    spec = ClothSpec(nx=5, ny=5, k_stretch=1000, k_shear=0, k_bend=0, damping=0, mass=0.25)
    cloth = Cloth(spec, ForceSet([Gravity()]))
    m = 0.25 / 25
    # Gershgorin: omega^2 <= 2 * (4 k) / m in the grid interior
    assert cloth.omega_max == pytest.approx(math.sqrt(2 * 4 * 1000 / m))
    assert cloth.stable_step() == pytest.approx(2 / cloth.omega_max)
    with caplog.at_level(logging.WARNING):
        cloth.advance(1 / 24, 1)
    assert "stability limit" in caplog.text


def test_bad_spec():
    with pytest.raises(ValueError, match="pinned"):
        ClothSpec(nx=3, ny=3, pinned=(9,))
    with pytest.raises(ValueError, match="nx"):
        ClothSpec(nx=1)
