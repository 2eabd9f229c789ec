"""Evaluate a reconstruction against ground truth: the yardstick for every method.

Both surfaces are sampled uniformly (area-weighted) at one shared density; a
point cloud is used as is (voxel-thinned to the same spacing). Nearest-neighbour
distances both ways give

* **precision** -- fraction of reconstruction samples within ``tau`` of the
  reference; **recall** -- fraction of reference samples within ``tau`` of the
  reconstruction; **F-score** ``2PR / (P + R)`` (Tanks and Temples, Knapitsch et
  al. 2017, doi:10.1145/3072959.3073599);
* **accuracy** (reconstruction -> reference) and **completeness** (reference ->
  reconstruction), mean and median (DTU, Aanæs et al. 2016,
  doi:10.1007/s11263-016-0902-9);
* **Chamfer distance** = accuracy mean + completeness mean (the *sum*
  convention); **overall** = their average (DTU's "overall");
* **Hausdorff** = the larger directed maximum; **hausdorff_95** = the larger
  directed 95th percentile;
* **normal consistency** = the mean of ``|n . n_nearest|`` over both directions
  (Mescheder et al. 2019), when both sides carry normals (mesh samples always do).

Distances
---------
With ``distance="surface"`` (the default) a sample's distance to a mesh is to the closest
point of its triangles (exact: a mesh scored against itself gives 0 whatever the
density), to a point cloud the nearest point. With ``"samples"`` it is to the nearest
sample of the other side, the Tanks and Temples / DTU protocol, which adds a sampling
error of about ``1 / (2 pi density d)`` to a gap ``d`` and about half the spacing to a gap
of 0; the default density ties the spacing to ``tau`` (about ``tau / 2.8``). A
reconstruction in its own frame can be aligned first: ``"icp"`` from the identity
(point-to-plane when the reference samples have normals), ``"global"`` from any frame
(a deterministic coarse registration first).

Example
-------
>>> import open3d as o3d
>>> gt = o3d.geometry.TriangleMesh.create_sphere(0.05, resolution=40)
>>> res = evaluate(gt, gt, rng=np.random.default_rng(0))
>>> round(res.fscore, 3)
1.0
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import asdict, dataclass

import numpy as np

from core.config import Config, option
from core.frames import transform_points
from core.sampling import sample_surface, voxel_thin
from core.validate import check_array, check_choice, check_positive

__all__ = ["EvaluateConfig",
    "EvaluationResult",
    "evaluate",
    "fscore_at",
    "default_tau",
    "TAU_FRACTION",
    "SAMPLES_PER_TAU2",
    "DEFAULT_MAX_SAMPLES",
]

log = logging.getLogger(__name__)

#: Default ``tau`` as a fraction of the reference's bounding-box diagonal.
TAU_FRACTION = 0.005
#: Default density (samples per m^2) is ``SAMPLES_PER_TAU2 / tau**2``: mean spacing
#: about ``tau / 2.8``, so a sample misses every neighbour within ``tau`` on the
#: same surface with probability ``exp(-pi * 8) ~ 1e-11`` (Poisson sampling).
SAMPLES_PER_TAU2 = 8.0
#: Default cap on the samples drawn per side (for speed); a 15 cm object reaches it.
DEFAULT_MAX_SAMPLES = 200_000


@dataclass(frozen=True)
class EvaluationResult:
    """Figures of one evaluation; distances in metres.

    Attributes
    ----------
    tau : float
        Distance threshold of precision, recall and F-score.
    precision, recall, fscore : float
        In [0, 1], at ``tau``.
    accuracy_mean, accuracy_median : float
        Distances from reconstruction samples to the nearest reference sample.
    completeness_mean, completeness_median : float
        Distances from (visible) reference samples to the nearest reconstruction sample.
    chamfer : float
        ``accuracy_mean + completeness_mean`` (sum convention).
    overall : float
        ``chamfer / 2`` (DTU's "overall").
    hausdorff, hausdorff_95 : float
        Max of the two directed maxima / of the two directed 95th percentiles.
    normal_consistency : float or None
        Mean ``|n . n_nearest|`` over both directions; None without normals on a side.
    n_recon_samples, n_reference_samples : int
        Samples used; ``n_reference_samples`` counts those the visibility mask kept.
    density : float
        Sampling density used for meshes, samples per m^2 (spacing ``1 / sqrt``).
    distance : {"surface", "samples"}
        How distances were measured (see :func:`evaluate`).
    icp_fitness, icp_inlier_rmse : float or None
        The alignment's final ICP figures when aligned (fraction of inliers within the
        threshold, their RMS distance).
    icp_reference_from_recon : (4, 4) tuple of tuples or None
        Rigid transform applied to the reconstruction before scoring.
    alignment : dict or None
        How it was aligned (:meth:`reconstruct.registration.icp.Registration.to_dict`):
        method, threshold, and for ``global`` the coarse stage's source and fitness.
    bias : float or None
        Mean signed distance of the reconstruction's samples within ``tau`` of the
        reference, along the reference triangle's normal (positive on the side it points
        to, outside for an outward mesh): a surface scanned too far out or in. None when
        the reference is not a mesh or distances are to samples.
    """

    tau: float
    precision: float
    recall: float
    fscore: float
    accuracy_mean: float
    accuracy_median: float
    completeness_mean: float
    completeness_median: float
    chamfer: float
    overall: float
    hausdorff: float
    hausdorff_95: float
    normal_consistency: float | None
    n_recon_samples: int
    n_reference_samples: int
    density: float
    distance: str = "surface"
    icp_fitness: float | None = None
    icp_inlier_rmse: float | None = None
    icp_reference_from_recon: tuple | None = None
    alignment: dict | None = None
    bias: float | None = None

    def to_dict(self) -> dict:
        """Plain JSON-ready dict of every field (None stays None)."""
        return asdict(self)

    def table(self) -> str:
        """The figures as a plain-text two-column table (no trailing newline)."""
        rows = [
            ("tau", _m(self.tau)),
            ("precision", f"{self.precision:.4f}"),
            ("recall", f"{self.recall:.4f}"),
            ("F-score", f"{self.fscore:.4f}"),
            ("accuracy mean", _m(self.accuracy_mean)),
            ("accuracy median", _m(self.accuracy_median)),
            ("completeness mean", _m(self.completeness_mean)),
            ("completeness median", _m(self.completeness_median)),
            ("Chamfer (acc + comp)", _m(self.chamfer)),
            ("overall (mean of both)", _m(self.overall)),
            ("Hausdorff", _m(self.hausdorff)),
            ("Hausdorff 95%", _m(self.hausdorff_95)),
            ("bias (signed, inliers)", "n/a" if self.bias is None else _m(self.bias)),
            ("normal consistency", "n/a" if self.normal_consistency is None
             else f"{self.normal_consistency:.4f}"),
            ("recon samples", f"{self.n_recon_samples}"),
            ("reference samples", f"{self.n_reference_samples}"),
            ("sample spacing", _m(1.0 / np.sqrt(self.density))),
            ("distances to", "mesh surface / nearest point" if self.distance == "surface"
             else "nearest sample"),
        ]
        if self.icp_fitness is not None:
            t = np.asarray(self.icp_reference_from_recon)
            how = (self.alignment or {}).get("method", "icp")
            rows += [("alignment", how),
                     ("alignment fitness", f"{self.icp_fitness:.4f}"),
                     ("alignment inlier RMSE", _m(self.icp_inlier_rmse)),
                     ("alignment rotation", f"{_rotation_deg(t[:3, :3]):.4g} deg"),
                     ("alignment translation",
                      "[" + ", ".join(f"{x:.6g}" for x in t[:3, 3]) + "] m")]
        width = max(len(k) for k, _ in rows)
        return "\n".join(f"{k:<{width}}  {v}" for k, v in rows)


def _rotation_deg(r: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip((np.trace(r) - 1) / 2, -1.0, 1.0))))


def _m(x: float) -> str:
    return f"{x:.6g} m"


def fscore_at(accuracy_distances: np.ndarray, completeness_distances: np.ndarray,
              tau: float) -> tuple[float, float, float]:
    """Precision, recall and F-score at ``tau`` from directed distances.

    Parameters
    ----------
    accuracy_distances : (n,) float64
        Reconstruction -> reference distances.
    completeness_distances : (m,) float64
        Reference -> reconstruction distances.
    tau : float
        Threshold in metres (a distance equal to ``tau`` counts as within).

    Returns
    -------
    (precision, recall, fscore) : floats in [0, 1]; F is 0 when P + R is 0.

    >>> fscore_at(np.array([0.0, 2.0]), np.array([0.0, 0.0]), 1.0)
    (0.5, 1.0, 0.6666666666666666)
    """
    acc = check_array(accuracy_distances, "accuracy_distances", shape=(None,), min_rows=1)
    comp = check_array(completeness_distances, "completeness_distances", shape=(None,),
                       min_rows=1)
    tau = check_positive(tau, "tau")
    p = float(np.mean(acc <= tau))
    r = float(np.mean(comp <= tau))
    f = 0.0 if p + r == 0 else 2.0 * p * r / (p + r)
    return p, r, f


# ----------------------------------------------------------------------------- inputs
@dataclass
class _Geom:
    name: str
    vertices: np.ndarray            # mesh vertices, or the points of a cloud
    triangles: np.ndarray | None    # None: a point cloud
    normals: np.ndarray | None      # point normals (clouds only)

    @property
    def is_mesh(self) -> bool:
        return self.triangles is not None

    def area(self) -> float:
        tri = self.vertices[self.triangles]
        return 0.5 * float(np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]),
                                          axis=1).sum())


def _as_geom(geom, name: str) -> _Geom:
    """Accept an open3d mesh / point cloud, an (n, 3) array or a (vertices, triangles) pair."""
    if hasattr(geom, "triangles") and hasattr(geom, "vertices"):  # open3d TriangleMesh
        v = check_array(np.asarray(geom.vertices), f"{name} vertices", shape=(None, 3))
        if len(v) == 0:
            raise ValueError(f"{name}: expected a non-empty mesh, got no vertices")
        f = np.asarray(geom.triangles, dtype=np.int64).reshape(-1, 3)
        if len(f) == 0:  # vertices only: a point cloud in a mesh's clothes
            n = np.asarray(geom.vertex_normals) if geom.has_vertex_normals() else None
            return _Geom(name, v, None, _normals(n, len(v), name))
        return _mesh_geom(name, v, f)
    if hasattr(geom, "points"):  # open3d PointCloud
        p = check_array(np.asarray(geom.points), f"{name} points", shape=(None, 3))
        if len(p) == 0:
            raise ValueError(f"{name}: expected a non-empty point cloud, got no points")
        n = np.asarray(geom.normals) if geom.has_normals() else None
        return _Geom(name, p, None, _normals(n, len(p), name))
    if isinstance(geom, tuple) and len(geom) == 2:
        v = check_array(geom[0], f"{name} vertices", shape=(None, 3), min_rows=3)
        f = check_array(geom[1], f"{name} triangles", shape=(None, 3), dtype=np.int64,
                        min_rows=1)
        return _mesh_geom(name, v, f)
    p = check_array(geom, name, shape=(None, 3), min_rows=1)
    return _Geom(name, p, None, None)


def _mesh_geom(name: str, v: np.ndarray, f: np.ndarray) -> _Geom:
    if f.min() < 0 or f.max() >= len(v):
        raise ValueError(f"{name} triangles: expected indices in [0, {len(v)}), "
                         f"got [{f.min()}, {f.max()}]")
    g = _Geom(name, v, f, None)
    if not g.area() > 0:
        raise ValueError(f"{name}: expected a mesh with positive surface area, got 0 "
                         f"({len(f)} degenerate triangles)")
    return g


def _normals(n: np.ndarray | None, count: int, name: str) -> np.ndarray | None:
    if n is None or len(n) != count:
        return None
    n = check_array(n, f"{name} normals", shape=(count, 3))
    norm = np.linalg.norm(n, axis=1, keepdims=True)
    if np.any(norm == 0):
        return None
    return n / norm


# ----------------------------------------------------------------------------- sampling
def _samples(g: _Geom, density: float, max_samples: int | None, thin: bool,
             rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray | None]:
    if g.is_mesh:
        n = max(1, int(round(density * g.area())))
        return sample_surface(g.vertices, g.triangles, n, rng=rng)
    pts, nrm = g.vertices, g.normals
    if thin:
        keep = voxel_thin(pts, 1.0 / np.sqrt(density))
        pts, nrm = pts[keep], (None if nrm is None else nrm[keep])
    if max_samples is not None and len(pts) > max_samples:
        keep = np.sort(rng.choice(len(pts), size=max_samples, replace=False))
        pts, nrm = pts[keep], (None if nrm is None else nrm[keep])
    return pts, nrm


def default_tau(reference) -> float:
    """``TAU_FRACTION`` (0.5 %) of the reference's axis-aligned bounding-box diagonal."""
    g = reference if isinstance(reference, _Geom) else _as_geom(reference, "reference")
    diag = float(np.linalg.norm(g.vertices.max(axis=0) - g.vertices.min(axis=0)))
    if not diag > 0:
        raise ValueError("reference: expected a non-degenerate bounding box to set tau, "
                         "got a diagonal of 0 (pass tau)")
    return TAU_FRACTION * diag


@dataclass
class EvaluateConfig(Config):
    """Options of ``scanamp evaluate`` (the keyword arguments of :func:`evaluate`)."""

    tau: float | None = option(None, unit="m", range="(0, inf)",
                               help="F-score threshold (default: 0.5% of the reference's "
                                    "bounding-box diagonal)")
    align: str = option("none", choices=("none", "icp", "global"),
                        help="align RECON to the reference first: 'icp' from where it is, "
                             "'global' from any frame (a turntable, SfM or handheld scan: "
                             "seeded coarse registration, then ICP)")
    distance: str = option("surface", choices=("surface", "samples"),
                           help="measure to the other mesh's surface (exact) or to its nearest "
                                "sample (the Tanks and Temples / DTU protocol)")
    seed: int = option(0, range="[0, inf)", help="sampling and registration seed")
    density: float | None = option(None, unit="1/m^2", range="(0, inf)",
                                   help="samples per square metre (default: 8 / tau^2)")
    max_samples: int = option(DEFAULT_MAX_SAMPLES, range="[1000, inf)",
                              help="cap on samples per side")


# ----------------------------------------------------------------------------- main
def evaluate(
    recon,
    reference,
    *,
    tau: float | None = None,
    density: float | None = None,
    icp: bool = False,
    icp_threshold: float | None = None,
    align: str | None = None,
    reference_mask: Callable[[np.ndarray], np.ndarray] | None = None,
    thin_points: bool = True,
    distance: str = "surface",
    rng: np.random.Generator | None = None,
    max_samples: int | None = DEFAULT_MAX_SAMPLES,
) -> EvaluationResult:
    """Score a reconstruction against a reference surface (see the module docstring).

    Parameters
    ----------
    recon, reference : open3d TriangleMesh or PointCloud, (n, 3) array or (vertices, triangles)
        A mesh is sampled uniformly by area; a point cloud (or a mesh with no triangles)
        is its own samples, voxel-thinned to the sample spacing when ``thin_points``.
    tau : float, optional
        Precision/recall/F threshold in metres; default 0.5 % of the reference's
        bounding-box diagonal (always reported).
    density : float, optional
        Mesh samples per m^2 on both sides; default ``SAMPLES_PER_TAU2 / tau**2``.
    icp, icp_threshold, align
        Alignment before scoring: ``align`` "none", "icp" (``icp=True``) or "global"
        (:func:`reconstruct.registration.rigid.register`); ICP's final correspondence
        distance ``icp_threshold``, default ``5 * tau``.
    reference_mask : callable, optional
        ``(n, 3) -> (n,) bool``: the reference samples that count for recall and
        completeness (what the scanner could see); precision uses the whole reference.
    distance : {"surface", "samples"}
        To the closest point of the other mesh's triangles (exact), or to its nearest
        sample (the Tanks and Temples / DTU protocol); see "Distances" above.
    rng : numpy.random.Generator, optional
        Sampling randomness; default ``numpy.random.default_rng(0)``.
    max_samples : int or None
        Cap on samples per side (the shared density is lowered to meet it).

    Raises ValueError for empty or degenerate input, a bad option, or a mask of the
    wrong shape or keeping nothing (messages start with ``recon`` or ``reference``).
    """
    rng = np.random.default_rng(0) if rng is None else rng
    check_choice(distance, "distance", {"surface", "samples"})
    rec = _as_geom(recon, "recon")
    ref = _as_geom(reference, "reference")
    tau = default_tau(ref) if tau is None else check_positive(tau, "tau")
    density = SAMPLES_PER_TAU2 / tau**2 if density is None else check_positive(density, "density")
    if max_samples is not None:
        max_samples = int(check_positive(max_samples, "max_samples"))
        density = _capped_density(density, max_samples, rec, ref)
    rec_pts, rec_nrm = _samples(rec, density, max_samples, thin_points, rng)
    ref_pts, ref_nrm = _samples(ref, density, max_samples, thin_points, rng)

    align = ("icp" if icp else "none") if align is None else align
    threshold = 5.0 * tau if icp_threshold is None else icp_threshold
    rec, rec_pts, rec_nrm, icp_fields = _align(rec, rec_pts, rec_nrm, ref_pts, ref_nrm, align,
                                               threshold, rng)
    surface = distance == "surface"
    acc, acc_nrm, signed = _nearest(rec_pts, ref_pts, ref_nrm, ref if surface else None)
    visible = _visible(reference_mask, ref_pts)
    comp, comp_nrm, _ = _nearest(ref_pts[visible], rec_pts, rec_nrm,
                                 rec if surface else None)
    inliers = acc <= tau
    bias = (float(signed[inliers].mean()) if signed is not None and inliers.any()
            else None)

    consistency = None
    if rec_nrm is not None and ref_nrm is not None:
        c_acc = np.abs(np.einsum("ij,ij->i", rec_nrm, acc_nrm))
        c_comp = np.abs(np.einsum("ij,ij->i", ref_nrm[visible], comp_nrm))
        consistency = float(0.5 * (c_acc.mean() + c_comp.mean()))
    return _result(acc, comp, tau, normal_consistency=consistency,
                   n_recon_samples=len(rec_pts), n_reference_samples=int(visible.sum()),
                   density=float(density), distance=distance, bias=bias, **icp_fields)


def _result(acc: np.ndarray, comp: np.ndarray, tau: float, **fields):
    """The scores of the two directed distance sets."""
    precision, recall, fscore = fscore_at(acc, comp, tau)
    acc_mean, comp_mean = float(acc.mean()), float(comp.mean())
    return EvaluationResult(
        tau=float(tau), precision=precision, recall=recall, fscore=fscore,
        accuracy_mean=acc_mean, accuracy_median=float(np.median(acc)),
        completeness_mean=comp_mean, completeness_median=float(np.median(comp)),
        chamfer=acc_mean + comp_mean, overall=0.5 * (acc_mean + comp_mean),
        hausdorff=float(max(acc.max(), comp.max())),
        hausdorff_95=float(max(np.percentile(acc, 95), np.percentile(comp, 95))), **fields)


def _capped_density(density: float, max_samples: int, rec: _Geom, ref: _Geom) -> float:
    """The shared sampling density, lowered so no mesh side exceeds ``max_samples``."""
    areas = [g.area() for g in (rec, ref) if g.is_mesh]
    if areas and density * max(areas) > max_samples:
        density = max_samples / max(areas)
        log.debug("density capped to %.4g samples/m^2 by max_samples=%d", density, max_samples)
    return density


def _align(rec: _Geom, rec_pts, rec_nrm, ref_pts, ref_nrm, method: str, threshold: float,
           rng) -> tuple:
    """The reconstruction moved onto the reference (``icp`` or ``global``; ``none`` leaves
    it), and the report fields of the alignment."""
    from reconstruct.registration.rigid import register

    if check_choice(method, "align", ("none", "icp", "global")) == "none":
        return rec, rec_pts, rec_nrm, {}
    check_positive(threshold, "icp_threshold")

    reg = register(rec_pts, ref_pts, method=method, reference_normals=ref_nrm,
                   threshold=threshold, rng=rng)
    rot = reg.transform[:3, :3]
    rec = _Geom(rec.name, transform_points(reg.transform, rec.vertices), rec.triangles,
                None if rec.normals is None else rec.normals @ rot.T)
    fields = dict(icp_fitness=reg.fitness, icp_inlier_rmse=reg.inlier_rmse,
                  icp_reference_from_recon=tuple(map(tuple, reg.transform.tolist())),
                  alignment={k: v for k, v in reg.to_dict().items()
                             if k not in ("reference_from_scan", "fitness", "inlier_rmse_m")})
    return (rec, transform_points(reg.transform, rec_pts),
            None if rec_nrm is None else rec_nrm @ rot.T, fields)


def _visible(reference_mask, ref_pts: np.ndarray) -> np.ndarray:
    """Which reference samples count for recall (all without a mask)."""
    if reference_mask is None:
        return np.ones(len(ref_pts), dtype=bool)
    visible = np.asarray(reference_mask(ref_pts))
    if visible.shape != (len(ref_pts),) or visible.dtype != bool:
        raise ValueError(f"reference_mask: expected a ({len(ref_pts)},) bool array, got "
                         f"{visible.shape} {visible.dtype}")
    if not visible.any():
        raise ValueError("reference_mask: expected to keep some reference samples, kept none")
    return visible


def _nearest(query: np.ndarray, samples: np.ndarray, sample_normals: np.ndarray | None,
             mesh: _Geom | None) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
    """Distances from ``query (n, 3)`` to the mesh surface when ``mesh`` is one, else to
    the nearest of ``samples``; with the normal there (None when unknown) and, to a mesh,
    the signed distances along its triangles' normals (else None)."""
    if mesh is None or not mesh.is_mesh:
        from scipy.spatial import cKDTree

        dist, idx = cKDTree(samples).query(query, workers=-1)
        return dist, None if sample_normals is None else sample_normals[idx], None
    import open3d as o3d

    # Embree works in float32: centre the coordinates so large offsets cost no precision
    centre = mesh.vertices.mean(axis=0)
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor((mesh.vertices - centre).astype(np.float32)),
                        o3d.core.Tensor(mesh.triangles.astype(np.uint32)))
    q = query - centre
    ans = scene.compute_closest_points(o3d.core.Tensor(q.astype(np.float32)))
    off = q - ans["points"].numpy().astype(np.float64)
    normals = ans["primitive_normals"].numpy().astype(np.float64)
    normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-300)
    return np.linalg.norm(off, axis=1), normals, np.einsum("ij,ij->i", off, normals)
