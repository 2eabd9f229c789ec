import numpy as np
import pytest

from procgen.noise import perlin


def test_reference_value():
    # Perlin's Java reference gives this value at (3.14, 42, 7).
    assert perlin(3.14, 42, 7) == pytest.approx(0.13691995878400012, abs=1e-12)


def test_zero_on_lattice(rng):
    ijk = rng.integers(-300, 300, size=(3, 1000)).astype(float)
    assert np.all(perlin(*ijk) == 0.0)
    assert np.all(perlin(ijk[0]) == 0.0)
    assert np.all(perlin(ijk[0], ijk[1], seed=7) == 0.0)


def _reference_scalar(x, y, z, p):
    """Transcription of Perlin's reference with its branchy grad, as an oracle."""
    def fade(t):
        return t * t * t * (t * (t * 6 - 15) + 10)

    def lerp(t, a, b):
        return a + t * (b - a)

    def grad(h, x, y, z):
        h &= 15
        u = x if h < 8 else y
        v = y if h < 4 else (x if h in (12, 14) else z)
        return (u if h & 1 == 0 else -u) + (v if h & 2 == 0 else -v)

    X, Y, Z = int(np.floor(x)) & 255, int(np.floor(y)) & 255, int(np.floor(z)) & 255
    x, y, z = x - np.floor(x), y - np.floor(y), z - np.floor(z)
    u, v, w = fade(x), fade(y), fade(z)
    A = p[X] + Y; AA = p[A] + Z; AB = p[A + 1] + Z  # noqa: E702
    B = p[X + 1] + Y; BA = p[B] + Z; BB = p[B + 1] + Z  # noqa: E702
    return lerp(w, lerp(v, lerp(u, grad(p[AA], x, y, z), grad(p[BA], x - 1, y, z)),
                        lerp(u, grad(p[AB], x, y - 1, z), grad(p[BB], x - 1, y - 1, z))),
                lerp(v, lerp(u, grad(p[AA + 1], x, y, z - 1), grad(p[BA + 1], x - 1, y, z - 1)),
                     lerp(u, grad(p[AB + 1], x, y - 1, z - 1),
                          grad(p[BB + 1], x - 1, y - 1, z - 1))))


@pytest.mark.parametrize("seed", [None, 0, 99])
def test_matches_branchy_reference(rng, seed):
    from procgen.noise import perm_table

    p = perm_table(seed)
    pts = rng.uniform(-50, 50, size=(200, 3))
    ours = perlin(pts[:, 0], pts[:, 1], pts[:, 2], seed=seed)
    ref = [_reference_scalar(*q, p) for q in pts]
    np.testing.assert_allclose(ours, ref, rtol=0, atol=1e-15)


def test_seeds_are_reproducible_and_distinct(rng):
    pts = rng.uniform(0, 10, size=(3, 500))
    a = perlin(*pts, seed=5)
    assert a.tobytes() == perlin(*pts, seed=5).tobytes()
    assert not np.allclose(a, perlin(*pts, seed=6))
    assert not np.allclose(a, perlin(*pts))


def test_broadcast_and_range(rng):
    x = rng.uniform(-20, 20, size=(64, 1))
    y = rng.uniform(-20, 20, size=(1, 32))
    out = perlin(x, y)
    assert out.shape == (64, 32)
    assert np.abs(out).max() <= 1.0


def test_rejects_nonfinite_and_bad_seed():
    with pytest.raises(ValueError, match="finite"):
        perlin(np.array([0.5, np.inf]))
    with pytest.raises(ValueError, match="seed"):
        perlin(0.5, seed="abc")
