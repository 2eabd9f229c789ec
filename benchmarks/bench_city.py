"""Cities: the street statistics of each pattern, measured on the written ``roads.geojson``
as Boeing (2019) measures real cities, the city's own rules (no road in water, no building
over a road or another building, every lot on a street), and the time of a 2 km city of
about a thousand buildings against its 60 s bound (2 cores).

Real cities for comparison (Boeing 2019, table 1 and figure 3): orientation order phi
Chicago 0.90, Manhattan 0.65 (its grid is rotated), Charlotte 0.002, Boston 0.04;
mean node degree 2.6-3.6; dead-end share mostly below 0.3; circuity 1.02-1.10.
"""

import json
import tempfile
import time
from pathlib import Path

import numpy as np

from procgen.city import CityConfig, generate_city, overlaps, street_statistics
from procgen.city.io import write_city_files


def _from_geojson(path: Path):
    """Nodes and edges back from the written LineStrings (shared end points merged)."""
    feats = json.loads(path.read_text())["features"]
    index, nodes, edges = {}, [], []
    for f in feats:
        ends = []
        for xy in f["geometry"]["coordinates"]:
            key = (round(xy[0], 3), round(xy[1], 3))
            if key not in index:
                index[key] = len(nodes)
                nodes.append(key)
            ends.append(index[key])
        edges.append(ends)
    return np.array(nodes, float), np.array(edges, np.int64)


def main():
    targets = {"grid": (0.6, None), "organic": (None, 0.2), "radial": (None, None),
               "elevation": (None, None)}
    print("   pattern   | phi   | degree | dead ends | circuity | buildings | own rules")
    misses = 0
    with tempfile.TemporaryDirectory(dir=Path(__file__).parent) as tmp:
        for pattern, (phi_lo, phi_hi) in targets.items():
            row = []
            for seed in (0, 1, 2):
                city = generate_city(np.random.default_rng(seed),
                                     CityConfig(size=1200, max_segments=300, pattern=pattern))
                out = Path(tmp) / f"{pattern}{seed}.ply"
                write_city_files(city, out)
                nodes, edges = _from_geojson(out.with_name(f"{pattern}{seed}.roads.geojson"))
                s = street_statistics(nodes, edges)
                bad = overlaps(city)
                row.append((s["orientation_order"], s["mean_degree"], s["dead_end_share"],
                            s["circuity"], len(city.buildings), sum(bad.values())))
            r = np.array(row)
            ok = (np.all((r[:, 1] >= 2.5) & (r[:, 1] <= 3.6)) and np.all(r[:, 2] <= 0.3)
                  and np.all((r[:, 3] >= 1.0) & (r[:, 3] <= 1.2)) and np.all(r[:, 5] == 0)
                  and (phi_lo is None or np.all(r[:, 0] >= phi_lo))
                  and (phi_hi is None or np.all(r[:, 0] <= phi_hi)))
            misses += not ok
            print(f"   {pattern:9} | {r[:, 0].min():.2f}-{r[:, 0].max():.2f} | "
                  f"{r[:, 1].mean():.2f}   | {r[:, 2].mean():.3f}     | {r[:, 3].mean():.3f}    "
                  f"| {r[:, 4].mean():6.0f}    | {r[:, 5].sum():.1f} m/m2 off   "
                  f"{'PASS' if ok else 'MISS'}  (3 seeds)", flush=True)
        cfg = CityConfig(size=2000, max_segments=600)
        t, c = time.perf_counter(), time.process_time()
        city = generate_city(np.random.default_rng(0), cfg)
        write_city_files(city, Path(tmp) / "big.ply")
        dt, cpu = time.perf_counter() - t, time.process_time() - c
        ok = dt <= 60.0
        misses += not ok
        print(f"   2 km city: {len(city.buildings)} buildings, {len(city.edges)} road segments, "
              f"{len(city.triangles) / 1e6:.2f} M triangles in {dt:.1f} s (CPU {cpu:.1f} s) "
              f"(target <= 60 s) {'PASS' if ok else 'MISS'}", flush=True)
    return misses


if __name__ == "__main__":
    main()
