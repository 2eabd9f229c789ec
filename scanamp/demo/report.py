"""The demo's figures and ``report.html`` (I/O of :mod:`scanamp.demo`).

Renders use :func:`acquire.render.renderer.render` (the project's ray caster): the ground truth and
every reconstruction from one camera, each reconstruction's error map (distance to the
ground truth per pixel), and a close-up of the best reconstruction before and after
amplification. Plots use matplotlib (Agg). Every file the HTML references is relative to
the report's folder, so the folder opens from disk and can be moved as a whole.
"""

from __future__ import annotations

import html
import logging
import os
from pathlib import Path

import numpy as np

log = logging.getLogger(__name__)

__all__ = ["figures", "write_html", "comparison_camera", "referenced_files"]

_COLORS = {"laser": "#d62728", "stereo": "#1f77b4", "sfm": "#2ca02c"}
_GT_ALBEDO = (0.7, 0.68, 0.62)
_RECON_ALBEDO = (0.62, 0.66, 0.72)


def comparison_camera(width: int, height: int, *, distance: float = 0.36,
                      target=(0.0, 0.0, 0.02), elevation_deg: float = 35.0,
                      azimuth_deg: float = -60.0, fov_deg: float = 45.0):
    """The look-at camera of the comparison renders (world frame, Z up)."""
    from acquire.camera import Camera

    el, az = np.radians(elevation_deg), np.radians(azimuth_deg)
    t = np.asarray(target, float)
    eye = t + distance * np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    return Camera.look_at(eye, t, width=int(width), height=int(height), fov_deg=fov_deg)


def _render(mesh, camera, lights, ambient, albedo):
    from acquire.render.materials import Material
    from acquire.render.renderer import render
    from acquire.render.scene import RenderScene, SceneObject
    from core.meshes import make_mesh, mesh_arrays

    v, f = mesh_arrays(mesh)
    m = make_mesh(v, f)
    m.compute_vertex_normals()
    scene = RenderScene([SceneObject("mesh", m, Material(kind="constant", albedo=albedo),
                                     np.eye(4), 0)], list(lights), ambient)
    return render(scene, camera, supersample=1)


def _to_u8(rgb: np.ndarray) -> np.ndarray:
    return (np.clip(rgb, 0.0, 1.0) * 255 + 0.5).astype(np.uint8)


def _error_image(r, dist_fn, tau: float) -> np.ndarray:
    """Shaded render coloured by the distance to the ground truth (0 .. 3 tau, turbo)."""
    import matplotlib

    cmap = matplotlib.colormaps["turbo"]
    img = np.zeros(r.radiance.shape, np.float64) + 0.08
    if r.mask.any():
        d = dist_fn(r.points[r.mask].astype(np.float64))
        lum = r.radiance[r.mask].mean(axis=1)
        lum = lum / max(float(np.percentile(lum, 99)), 1e-9)
        col = cmap(np.clip(d / (3.0 * tau), 0, 1) * 0.85 + 0.1)[:, :3]
        img[r.mask] = col * (0.45 + 0.55 * np.clip(lum, 0, 1))[:, None]
    return img


def figures(root: Path, bundle, gt, methods: dict, amplified, dists: dict, *, tau: float,
            size=(400, 300), best: str) -> dict:
    """Write the renders and plots under ``root/figures``; returns their relative paths
    (``renders``, ``errors``, ``amplify``, ``plots``) and the F-score curves."""
    from core.io.image import write_image
    from core.meshes import surface_distance
    from core.progress import track

    fig = root / "figures"
    fig.mkdir(exist_ok=True)
    lights = bundle.render_scene.lights
    ambient = 0.15
    cam = comparison_camera(*size)
    out = {"renders": {}, "errors": {}, "amplify": {}, "plots": {}, "curves": {}}
    gt_r = _render(gt, cam, lights, ambient, _GT_ALBEDO)
    k = 0.85 / max(float(np.percentile(gt_r.radiance[gt_r.mask], 99)), 1e-9) \
        if gt_r.mask.any() else 1.0
    write_image(fig / "render_gt.png", _to_u8(np.where(gt_r.mask[..., None],
                                                        gt_r.radiance * k, 0.08)))
    out["renders"]["ground truth"] = "figures/render_gt.png"
    gt_dist = surface_distance(gt)
    for name, m in track(list(methods.items()), "renders", total=len(methods)):
        r = _render(m.mesh, cam, lights, ambient, _RECON_ALBEDO)
        write_image(fig / f"render_{name}.png",
                    _to_u8(np.where(r.mask[..., None], r.radiance * k, 0.08)))
        out["renders"][name] = f"figures/render_{name}.png"
        write_image(fig / f"error_{name}.png", _to_u8(_error_image(r, gt_dist, tau)))
        out["errors"][name] = f"figures/error_{name}.png"
    # amplification close-up: around the scanned object (the blob), best reconstruction
    obj = np.asarray(bundle.object_mesh("object").vertices)
    c = 0.5 * (obj.min(0) + obj.max(0))
    close = comparison_camera(*size, distance=0.14, target=c, elevation_deg=30.0,
                              azimuth_deg=-80.0)
    for tag, mesh in (("before", methods[best].mesh), ("after", amplified)):
        r = _render(mesh, close, lights, ambient, _RECON_ALBEDO)
        kk = 0.85 / max(float(np.percentile(r.radiance[r.mask], 99)), 1e-9) if r.mask.any() \
            else 1.0
        write_image(fig / f"amplify_{tag}.png",
                    _to_u8(np.where(r.mask[..., None], r.radiance * kk, 0.08)))
        out["amplify"][tag] = f"figures/amplify_{tag}.png"
    for tag in ("before", "after"):  # the amplifier's own views: in colour, by part
        if (root / "amplify" / f"{tag}.png").is_file():
            out["amplify"][f"{tag} (colour)"] = f"amplify/{tag}.png"
    if (root / "amplify" / "turntable.mp4").is_file():
        out["amplify"]["turntable"] = "amplify/turntable.mp4"
    out["plots"], out["curves"] = _plots(fig, dists, tau)
    _colorbar(fig / "error_scale.png", tau)
    out["plots"]["error scale"] = "figures/error_scale.png"
    return out


def _plots(fig: Path, dists: dict, tau: float) -> tuple[dict, dict]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from reconstruct.evaluation.evaluate import fscore_at

    taus = tau * np.geomspace(0.1, 10.0, 25)
    curves = {}
    f1, ax = plt.subplots(figsize=(5.2, 3.6), dpi=100)
    for name, d in dists.items():
        fs = [fscore_at(d["accuracy"], d["completeness"], t)[2] for t in taus]
        curves[name] = {"tau_m": taus.tolist(), "fscore": fs}
        ax.semilogx(taus * 1e3, fs, "-o", ms=3, color=_COLORS.get(name), label=name)
    ax.axvline(tau * 1e3, color="0.5", ls="--", lw=1, label=f"tau = {tau * 1e3:.2f} mm")
    ax.set_xlabel("tau (mm)")
    ax.set_ylabel("F-score")
    ax.set_ylim(0, 1.02)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(loc="lower right", fontsize=8)
    ax.set_title("F-score against the threshold tau")
    f1.tight_layout()
    f1.savefig(fig / "fscore_vs_tau.png")
    plt.close(f1)

    f2, axes = plt.subplots(1, 2, figsize=(9, 3.4), dpi=100, sharey=False)
    lo, hi = tau / 100.0, 10.0 * tau
    bins = np.geomspace(lo, hi, 41)
    for ax, key, title in ((axes[0], "accuracy", "accuracy: reconstruction -> truth"),
                           (axes[1], "completeness", "completeness: truth -> reconstruction")):
        for name, d in dists.items():
            x = np.clip(d[key], lo, hi)
            ax.hist(x * 1e3, bins=bins * 1e3, histtype="step", lw=1.5,
                    weights=np.full(len(x), 1.0 / max(len(x), 1)), color=_COLORS.get(name),
                    label=name)
        ax.axvline(tau * 1e3, color="0.5", ls="--", lw=1)
        ax.set_xscale("log")
        ax.set_xlabel("distance (mm; end bins gather the rest)")
        ax.set_title(title, fontsize=10)
        ax.grid(True, alpha=0.3)
    axes[0].set_ylabel("fraction of samples")
    axes[0].legend(fontsize=8)
    f2.tight_layout()
    f2.savefig(fig / "error_histograms.png")
    plt.close(f2)
    return ({"F-score vs tau": "figures/fscore_vs_tau.png",
             "error histograms": "figures/error_histograms.png"}, curves)


def _colorbar(path: Path, tau: float) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    f, ax = plt.subplots(figsize=(4.5, 0.9), dpi=100)
    grad = np.linspace(0.1, 0.95, 256)[None, :]
    ax.imshow(grad, aspect="auto", cmap="turbo", extent=(0, 3 * tau * 1e3, 0, 1), vmin=0,
              vmax=1)
    ax.set_yticks([])
    ax.set_xlabel("distance to the ground truth (mm)", fontsize=8)
    ax.tick_params(labelsize=8)
    f.tight_layout()
    f.savefig(path)
    plt.close(f)


# ----------------------------------------------------------------------------- HTML
def _mm(x) -> str:
    return "–" if x is None else f"{1e3 * x:.2f}"


def _img(src: str, caption: str, width: int | None = None) -> str:
    w = f' width="{width}"' if width else ""
    return (f'<figure><img src="{html.escape(src)}" alt="{html.escape(caption)}"{w}>'
            f"<figcaption>{html.escape(caption)}</figcaption></figure>")


def _video(src: str, caption: str) -> str:
    s = html.escape(src)
    return (f'<figure><video src="{s}" controls autoplay loop muted playsinline></video>'
            f'<figcaption>{html.escape(caption)} (<a href="{s}">file</a>)</figcaption></figure>')


_CSS = """
body { font-family: system-ui, sans-serif; margin: 2em auto; max-width: 1100px; color: #222; }
h1 { margin-bottom: 0.2em; } .sub { color: #666; margin-top: 0; }
table { border-collapse: collapse; margin: 1em 0; }
th, td { border-bottom: 1px solid #ddd; padding: 4px 10px; text-align: right; }
th:first-child, td:first-child { text-align: left; }
tr.best td { background: #eef7ee; font-weight: 600; }
figure { display: inline-block; margin: 6px; vertical-align: top; text-align: center; }
figcaption { font-size: 0.85em; color: #555; }
video { max-width: 480px; background: #111; }
img { max-width: 100%; }
code { background: #f4f4f4; padding: 1px 4px; }
"""


def referenced_files(text: str) -> list[str]:
    """Relative ``src``/``href`` targets of an HTML text (what must exist beside it)."""
    import re

    refs = re.findall(r'(?:src|href)="([^"#]+)"', text)
    return sorted({html.unescape(r) for r in refs if "://" not in r})


def write_html(path: str | os.PathLike, report: dict) -> list[str]:
    """Write ``report.html`` from the demo report; returns the files it references."""
    from core.files import atomic_file

    r = report
    tau = r["tau"]
    rows = []
    for m in r["methods"]:
        if not m["ok"]:
            rows.append(f"<tr><td>{html.escape(m['method'])}</td>"
                        f"<td colspan='9'>failed: {html.escape(str(m['error']))}</td></tr>")
            continue
        cls = ' class="best"' if m["method"] == r["best"] else ""
        rows.append(
            f"<tr{cls}><td title='{html.escape(m['label'])}'>{html.escape(m['method'])}</td>"
            f"<td>{m['points']:,}</td><td>{m['fscore']:.3f}</td><td>{m['precision']:.3f}</td>"
            f"<td>{m['recall']:.3f}</td><td>{_mm(m['accuracy_mean'])}</td>"
            f"<td>{_mm(m['completeness_mean'])}</td><td>{_mm(m['chamfer'])}</td>"
            f"<td>{m['seconds']:.1f}</td><td>{m['fscore_unaligned']:.3f}</td></tr>")
    notes = "".join(f"<li><b>{html.escape(m['method'])}</b>: {html.escape(m['label'])}; "
                    f"{html.escape(m['notes'])}; <a href=\"{html.escape(m['mesh'])}\">mesh</a>"
                    f"</li>" for m in r["methods"] if m["ok"])
    fig = r["figures"]
    renders = _img(fig["renders"]["ground truth"], "ground truth")
    renders += "".join(_img(fig["renders"][n], n) for n in fig["renders"] if n != "ground truth")
    errors = "".join(_img(fig["errors"][n], f"{n}: distance to the truth") for n in fig["errors"])
    errors += _img(fig["plots"]["error scale"], "colour scale (0 to 3 tau)")
    plots = "".join(_img(p, k) for k, p in fig["plots"].items() if k != "error scale")
    amp = r["amplify"]
    anim = r["animations"]
    recipe_link = (f' (<a href="{html.escape(amp["recipe_file"])}">recipe</a>)'
                   if amp.get("recipe_file") else "")
    timing_rows = "".join(f"<tr><td>{html.escape(k)}</td><td>{v:.2f}</td></tr>"
                          for k, v in r["timings"].items())
    body = f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>scanamp demo</title>
<style>{_CSS}</style></head><body>
<h1>scanamp demo</h1>
<p class="sub">scene <code>{html.escape(r['scene']['name'])}</code>, seed {r['seed']},
scale <code>{html.escape(r['scale'])}</code>, {r['timings']['total']:.1f} s in all.
Numbers: <a href="report.json">report.json</a>; the scene:
<a href="scene/scene.toml">scene.toml</a>.</p>

<h2>Reconstructions against the ground truth</h2>
<p>F-score, precision and recall at <b>tau = {tau * 1e3:.2f} mm</b> ({html.escape(r['tau_rule'])});
accuracy (reconstruction to truth) and completeness (visible truth to reconstruction) are mean
distances, Chamfer their sum; reference: {html.escape(r['reference'])}. Each reconstruction
is first aligned rigidly to the truth by ICP (its rig calibrates its own frame); "F unaligned"
scores it in the frame its calibration gave. Time: capture plus reconstruction.</p>
<table><tr><th>method</th><th>points</th><th>F-score</th><th>precision</th><th>recall</th>
<th>accuracy (mm)</th><th>completeness (mm)</th><th>Chamfer (mm)</th><th>time (s)</th>
<th>F unaligned</th></tr>
{''.join(rows)}</table>
<ul>{notes}</ul>
<h3>Renders (acquire.render.renderer, one camera)</h3>
<div>{renders}</div>
<h3>Error maps</h3>
<div>{errors}</div>
<h3>Plots</h3>
<div>{plots}</div>

<h2>Amplification of the best reconstruction ({html.escape(r['best'])})</h2>
<p>Recipe <code>{html.escape(str(amp['recipe']))}</code>{recipe_link}
({html.escape(', '.join(s['kind'] for s in amp['steps']))}): {amp['input']['triangles']:,} to
{amp['output']['triangles']:,} triangles (<a href="{html.escape(amp['mesh'])}">mesh</a>,
<a href="amplify/report.json">report</a>). Close-up on the scanned object, then the whole
scene in colour by part (ground, objects, plants):</p>
<div>{_img(fig['amplify']['before'], 'before')}{_img(fig['amplify']['after'], 'after')}</div>
<div>{''.join(_img(fig['amplify'][k], k) for k in ('before (colour)', 'after (colour)')
             if k in fig['amplify'])}{_video(fig['amplify']['turntable'], 'turntable')
             if 'turntable' in fig['amplify'] else ''}</div>

<h2>Animation on the amplified mesh</h2>
<div>{_video(anim['particles']['video'], 'snow settling (particles, recipe snow)')}
{_video(anim['boids']['video'], f"a flock of {anim['boids']['n']} boids (recipe flock)")}</div>
<p>The simulation recipes are authored in metres-sized worlds: the mesh is scaled to
{anim['particles']['collider_scale_m']:g} m (snow) and {anim['boids']['collider_scale_m']:g} m
(boids) across.</p>

<h2>Timings (s)</h2>
<table><tr><th>stage</th><th>seconds</th></tr>{timing_rows}</table>
</body></html>
"""
    with atomic_file(path) as tmp:
        Path(tmp).write_text(body, encoding="utf-8")
    return referenced_files(body)
