"""3-D Perlin throughput on 4 M random points against pyfastnoiselite's Perlin (same run)."""

import numpy as np
from _timing import best_of, report

from procgen.noise import perlin


def main():
    import pyfastnoiselite.pyfastnoiselite as fnl

    n = 4_000_000
    pts = np.random.default_rng(0).uniform(0, 100, size=(3, n))
    ours = best_of(lambda: perlin(pts[0], pts[1], pts[2]))
    noise = fnl.FastNoiseLite(0)
    noise.noise_type = fnl.NoiseType.NoiseType_Perlin
    noise.frequency = 1.0
    coords = np.ascontiguousarray(pts.astype(np.float32))
    peer = best_of(lambda: noise.gen_from_coords(coords))
    print(f"   perlin: {n / ours / 1e6:.1f} M points/s; FastNoiseLite: {n / peer / 1e6:.1f} M/s")
    report("perlin throughput vs FastNoiseLite", 1 / ours, 1 / peer, 1.0)


if __name__ == "__main__":
    main()
