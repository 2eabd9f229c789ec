"""The noise family: oracles from the definitions (explicit octave sums of perlin),
exact tiling, divergence-free curl noise, Perlin's bias and gain, solid textures."""

import numpy as np
import pytest

from procgen.noise import (
    SOLID_TEXTURES,
    bias,
    color_ramp,
    curl,
    fbm,
    fire_ramp,
    gain,
    marble,
    perlin,
    ridged,
    tileable,
    turbulence,
    warp,
)


@pytest.fixture
def pts(rng):
    return rng.uniform(-30, 30, size=(3, 500))


@pytest.mark.parametrize("seed", [None, 3])
def test_fbm_one_octave_is_perlin_exactly(pts, seed):
    x, y, z = pts
    assert np.array_equal(fbm(x, y, z, octaves=1, seed=seed), perlin(x, y, z, seed=seed))
    assert np.array_equal(fbm(x, y, octaves=1, seed=seed), perlin(x, y, seed=seed))
    assert np.array_equal(fbm(x, octaves=1, seed=seed), perlin(x, seed=seed))


@pytest.mark.parametrize("lac,g", [(2.0, 0.5), (1.93, 0.6)])
def test_fbm_and_turbulence_are_the_octave_sums(pts, lac, g):
    x, y, z = pts
    ref_f = sum(g ** k * perlin(x * lac ** k, y * lac ** k, z * lac ** k) for k in range(5))
    ref_t = sum(g ** k * np.abs(perlin(x * lac ** k, y * lac ** k, z * lac ** k))
                for k in range(5))
    np.testing.assert_allclose(fbm(x, y, z, octaves=5, lacunarity=lac, gain=g), ref_f,
                               rtol=0, atol=1e-12)
    t = turbulence(x, y, z, octaves=5, lacunarity=lac, gain=g)
    np.testing.assert_allclose(t, ref_t, rtol=0, atol=1e-12)
    assert t.min() >= 0


def test_ridged_follows_musgrave(pts):
    x, y, z = pts
    lac, h, off, g = 2.0, 1.0, 1.0, 2.0
    sig = (off - np.abs(perlin(x, y, z))) ** 2
    total = sig.copy()
    for k in range(1, 3):
        w = np.clip(sig * g, 0, 1)
        s = lac ** k
        sig = (off - np.abs(perlin(x * s, y * s, z * s))) ** 2 * w
        total += sig * lac ** (-k * h)
    np.testing.assert_allclose(ridged(x, y, z, octaves=3), total, rtol=0, atol=1e-12)


def test_marble_is_sin_of_turbulence(pts):
    x, y, z = pts
    ref = np.sin(2.0 * x + 3.0 * turbulence(x, y, z, octaves=4))
    np.testing.assert_allclose(marble(x, y, z, frequency=2.0, strength=3.0, octaves=4), ref,
                               atol=1e-12)


def test_tileable_is_periodic_over_the_unit_square(rng):
    u, v = rng.uniform(0, 1, size=(2, 300))
    a = tileable(u, v, frequency=3, octaves=4, seed=2)
    for du, dv in [(1, 0), (0, 1), (-2, 3)]:
        np.testing.assert_allclose(tileable(u + du, v + dv, frequency=3, octaves=4, seed=2), a,
                                   atol=1e-9)
    # with time as a third (non-periodic) axis the tile still repeats, and it changes in t
    b = tileable(u, v, frequency=3, octaves=4, t=0.37, seed=2)
    np.testing.assert_allclose(tileable(u + 1, v, frequency=3, octaves=4, t=0.37, seed=2), b,
                               atol=1e-9)
    assert not np.allclose(a, b)


def test_tileable_with_period_256_is_perlin(rng):
    u, v = rng.uniform(0, 1, size=(2, 300))
    np.testing.assert_allclose(tileable(u, v, frequency=256, octaves=1),
                               perlin(256 * u, 256 * v), atol=1e-12)


def test_time_animates_2d_as_3d_and_3d_as_4d(pts):
    x, y, z = pts
    assert np.array_equal(fbm(x, y, t=z, octaves=3), fbm(x, y, z, octaves=3))
    a = fbm(x, y, z, t=0.0, octaves=1)
    b = fbm(x, y, z, t=0.25, octaves=1)
    c = fbm(x, y, z, t=0.25 + 1e-7, octaves=1)
    assert not np.allclose(a, b)
    assert np.abs(b - c).max() < 1e-5  # continuous in time
    lattice = np.arange(-3.0, 4.0)
    assert np.all(fbm(lattice, lattice, lattice, t=lattice, octaves=1) == 0.0)
    assert np.abs(fbm(x, y, z, t=x * 0.3, octaves=1)).max() <= 1.0


def test_warp_zero_is_fbm_and_nonzero_differs(pts):
    x, y, z = pts
    np.testing.assert_array_equal(warp(x, y, z, amount=0.0), fbm(x, y, z))
    assert not np.allclose(warp(x, y, z, amount=1.0), fbm(x, y, z))


def _fd_divergence(field, p, h=1e-5):
    div = 0.0
    for k in range(p.shape[0]):
        e = np.zeros((p.shape[0], 1))
        e[k] = h
        div = div + (field(p + e)[:, k] - field(p - e)[:, k]) / (2 * h)
    return div


def test_curl_noise_is_divergence_free(rng):
    p = rng.uniform(-5, 5, size=(3, 400))
    f3 = lambda q: curl(q[0], q[1], q[2], octaves=3, seed=1)  # noqa: E731
    div = _fd_divergence(f3, p)
    scale = np.abs(f3(p)).mean()
    assert np.abs(div).max() < 1e-5 * max(scale, 1.0)
    assert scale > 0.1  # not trivially zero
    f2 = lambda q: curl(q[0], q[1], t=0.3, octaves=2)  # noqa: E731
    assert np.abs(_fd_divergence(f2, p[:2])).max() < 1e-5


def test_curl_matches_finite_differences_of_the_potential(rng):
    # 2-D: v = (dpsi/dy, -dpsi/dx) with psi = fbm(x, y, t)
    x, y = rng.uniform(-5, 5, size=(2, 200))
    h = 1e-6
    v = curl(x, y, t=0.7, octaves=2)
    dpdy = (fbm(x, y + h, 0.7, octaves=2) - fbm(x, y - h, 0.7, octaves=2)) / (2 * h)
    dpdx = (fbm(x + h, y, 0.7, octaves=2) - fbm(x - h, y, 0.7, octaves=2)) / (2 * h)
    np.testing.assert_allclose(v[:, 0], dpdy, atol=1e-6)
    np.testing.assert_allclose(v[:, 1], -dpdx, atol=1e-6)


def test_bias_and_gain():
    t = np.linspace(0, 1, 101)
    assert bias(0.5, 0.8) == pytest.approx(0.8)
    assert gain(0.5, 0.2) == pytest.approx(0.5)
    np.testing.assert_allclose(bias(t, 0.5), t, atol=1e-15)
    np.testing.assert_allclose(gain(t, 0.5), t, atol=1e-15)
    for fn, p in [(bias, 0.3), (gain, 0.8), (gain, 0.2)]:
        y = fn(t, p)
        assert y[0] == 0 and y[-1] == pytest.approx(1.0) and np.all(np.diff(y) >= 0)
    # gain > 0.5 steepens the middle: below t at 0.25, above at 0.75
    assert gain(0.25, 0.8) < 0.25 < 0.75 < gain(0.75, 0.8)
    with pytest.raises(ValueError, match="b:"):
        bias(t, 1.0)
    with pytest.raises(ValueError, match="g:"):
        gain(t, 0.0)


def test_seeds_and_bad_input(pts):
    x, y, z = pts
    a = fbm(x, y, z, seed=5)
    assert a.tobytes() == fbm(x, y, z, seed=5).tobytes()
    assert not np.allclose(a, fbm(x, y, z, seed=6))
    with pytest.raises(ValueError, match="octaves"):
        fbm(x, octaves=0)
    with pytest.raises(ValueError, match="lacunarity"):
        turbulence(x, lacunarity=1.0)
    with pytest.raises(ValueError, match="finite"):
        fbm(np.array([0.1, np.nan]))
    with pytest.raises(ValueError, match="seed"):
        ridged(x, seed="x")
    with pytest.raises(ValueError, match="octaves"):
        tileable(x, y, frequency=64, octaves=4)


@pytest.mark.parametrize("name", sorted(SOLID_TEXTURES))
def test_solid_textures(rng, name):
    fn = SOLID_TEXTURES[name]
    p = rng.uniform(-1, 1, size=(2000, 3))
    c = fn(p, scale=0.3, seed=1)
    assert c.shape == (2000, 3) and c.dtype == np.float64
    assert c.min() >= 0 and c.max() <= 1
    assert c.tobytes() == fn(p, scale=0.3, seed=1).tobytes()
    assert not np.allclose(c, fn(p, scale=0.3, seed=2))
    assert c.std(axis=0).max() > 0.03  # textured, for stereo and SfM matching
    with pytest.raises(ValueError, match="points"):
        fn(p[:, :2])
    with pytest.raises(ValueError, match="scale"):
        fn(p, scale=0.0)


def test_color_ramp_and_fire_ramp():
    np.testing.assert_allclose(color_ramp([0.25], [0, 0.5, 1], [[0, 0, 0], [1, 0, 0], [1, 1, 1]]),
                               [[0.5, 0, 0]])
    f = fire_ramp(np.linspace(0, 1, 50))
    assert np.all(np.diff(f.sum(axis=1)) >= 0)  # hotter is brighter
    assert f[0].sum() < 0.1 and f[-1].min() > 0.8
    with pytest.raises(ValueError, match="stops"):
        color_ramp([0.5], [1, 0], [[0, 0, 0], [1, 1, 1]])
