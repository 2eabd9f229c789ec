"""fBm (5 octaves, 4 M points) against pyfastnoiselite's FBm, and diamond-square on
4097^2 against drawing as many normal numbers with numpy (same run)."""

import numpy as np
from _timing import best_of, report

from procgen.fractals import diamond_square
from procgen.noise import fbm


def main():
    import pyfastnoiselite.pyfastnoiselite as fnl

    n = 4_000_000
    pts = np.random.default_rng(0).uniform(0, 100, size=(3, n))
    ours = best_of(lambda: fbm(pts[0], pts[1], pts[2], octaves=5, lacunarity=2.0, gain=0.5))
    noise = fnl.FastNoiseLite(0)
    noise.noise_type = fnl.NoiseType.NoiseType_Perlin
    noise.fractal_type = fnl.FractalType.FractalType_FBm
    noise.fractal_octaves = 5
    noise.fractal_lacunarity = 2.0
    noise.fractal_gain = 0.5
    noise.frequency = 1.0
    coords = np.ascontiguousarray(pts.astype(np.float32))
    peer = best_of(lambda: noise.gen_from_coords(coords))
    print(f"   fbm (5 octaves): {n / ours / 1e6:.1f} M points/s; "
          f"FastNoiseLite FBm: {n / peer / 1e6:.1f} M/s")
    report("fbm throughput vs FastNoiseLite FBm", 1 / ours, 1 / peer, 1.0)

    size = 4097
    ds = best_of(lambda: diamond_square(12, hurst=0.7, rng=np.random.default_rng(1)), repeat=2)
    normals = best_of(lambda: np.random.default_rng(1).standard_normal((size, size)), repeat=2)
    print(f"   diamond_square 4097^2: {ds:.2f} s; numpy normals: {normals:.2f} s")
    report("diamond-square time / numpy normals", ds, normals, 3.0, higher_is_better=False)


if __name__ == "__main__":
    main()
