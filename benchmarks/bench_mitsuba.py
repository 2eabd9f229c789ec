"""Our renderer against Mitsuba 3 (issue 17): the reference scenes (a sphere of each
material in a matte corner, a point light or a projected stripe pattern), rendered by
both at matched settings, direct light only; relative L1 error after the same tone map
(target <= 3 %) and on linear radiance, over the whole image and over the sphere alone;
one bounce against Mitsuba's max_depth 3; and the subsurface sphere against Mitsuba's
volumetric path tracer. Writes docs/img/mitsuba_reference.png (ours, Mitsuba, 10x
difference)."""

import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def main():
    from acquire.render.mitsuba_reference import (
        REFERENCE_MATERIALS,
        agreement,
        corner_scene,
        mitsuba_available,
        render_reference,
        tone_map,
    )
    from acquire.render.renderer import render

    if not mitsuba_available():
        print("   Mitsuba 3 is not installed (pip install -e .[dev]); skipped")
        return 0
    spp = 64
    print(f"   160x120, ours 4x4 supersampled, Mitsuba path tracer max_depth 2 (direct), "
          f"{spp} spp")
    print("   | light | sphere material | image: tone-mapped, linear | sphere: tone-mapped, "
          "linear | ours s | Mitsuba s |")
    print("   |---|---|---|---|---|---|")
    worst, panels = 0.0, []
    for light in ("point", "projector"):
        for m in REFERENCE_MATERIALS:
            if m.startswith("subsurface"):
                continue     # _subsurface: the volumetric reference needs more samples
            scene, cam = corner_scene(m, light=light)
            t = time.perf_counter()
            ours = render(scene, cam, supersample=4).radiance
            t_ours = time.perf_counter() - t
            t = time.perf_counter()
            ref = render_reference(scene, cam, spp=spp, seed=0)
            t_ref = time.perf_counter() - t
            ids = render(scene, cam, supersample=1).object_id
            a = agreement(ours, ref, ids)
            b = agreement(ours, ref, np.where(ids == 2, 2, -1))
            worst = max(worst, a.relative_l1, b.relative_l1)
            print(f"   | {light} | {m} | {100 * a.relative_l1:.2f} %, "
                  f"{100 * a.relative_l1_linear:.2f} % | {100 * b.relative_l1:.2f} %, "
                  f"{100 * b.relative_l1_linear:.2f} % | {t_ours:.2f} | {t_ref:.2f} |",
                  flush=True)
            if m in ("conductor r0.1", "dielectric r0.3"):
                panels.append((f"{light}, {m}", ours, ref))
    print(f"   worst tone-mapped relative L1: {100 * worst:.2f} % (target <= 3 %) "
          f"{'PASS' if worst <= 0.03 else 'MISS'}")
    _one_bounce(panels)
    _subsurface(panels)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(panels), 3, figsize=(9, 2.3 * len(panels)))
    for row, (title, ours, ref) in zip(axes, panels, strict=True):
        for ax, img, name in zip(row, (tone_map(ours), tone_map(ref),
                                       np.clip(10 * np.abs(tone_map(ours) - tone_map(ref)),
                                               0, 1)),
                                 ("scanamp", "Mitsuba 3", "|difference| x 10"), strict=True):
            ax.imshow(img)
            ax.set_title(f"{name}: {title}", fontsize=7)
            ax.set_axis_off()
    fig.tight_layout()
    out = ROOT / "docs" / "img" / "mitsuba_reference.png"
    fig.savefig(out, dpi=110)
    print(f"   wrote {out.relative_to(ROOT)}")
    return 0


def _one_bounce(panels):
    """Direct light plus one bounce against Mitsuba's max_depth 3. Ours: 8x8 rays per
    pixel, one indirect direction each, four seeds averaged (256 indirect samples per
    pixel); Mitsuba 1024 spp. Our Monte Carlo noise is measured as the difference between
    two halves of our samples (seeds 0-1 against 2-3), divided by sqrt 2 for the whole."""
    from acquire.render.mitsuba_reference import agreement, corner_scene, render_reference
    from acquire.render.renderer import render

    print("   one bounce: ours 8x8 rays x 4 seeds, Mitsuba max_depth 3 at 1024 spp")
    print("   | light | sphere | vs Mitsuba: tone-mapped, linear | our noise (tone-mapped) | "
          "error beyond noise | direct only vs Mitsuba |")
    print("   |---|---|---|---|---|---|")
    worst = 0.0
    for light in ("point", "projector"):
        for m in ("lambert", "conductor r0.1", "conductor r0.3", "dielectric r0.3"):
            scene, cam = corner_scene(m, light=light)
            runs = [render(scene, cam, supersample=8, bounces=1, seed=k).radiance
                    for k in range(4)]
            ours = np.mean(runs, axis=0)
            ref = render_reference(scene, cam, spp=1024, bounces=1, seed=0)
            ids = render(scene, cam, supersample=1).object_id
            a = agreement(ours, ref, ids)
            noise = agreement(np.mean(runs[:2], 0), np.mean(runs[2:], 0), ids).relative_l1
            noise /= 2.0   # two halves differ by sqrt 2 x (noise of a half) = 2 x the whole's
            beyond = max(a.relative_l1 - noise, 0.0)
            worst = max(worst, beyond)
            direct = agreement(render(scene, cam, supersample=4).radiance, ref, ids)
            print(f"   | {light} | {m} | {100 * a.relative_l1:.2f} %, "
                  f"{100 * a.relative_l1_linear:.2f} % | {100 * noise:.2f} % | "
                  f"{100 * beyond:.2f} % | {100 * direct.relative_l1:.2f} % |", flush=True)
    print(f"   worst one-bounce error beyond our noise: {100 * worst:.2f} % (target <= 8 %) "
          f"{'PASS' if worst <= 0.08 else 'MISS'}")


def _subsurface(panels):
    """The subsurface sphere (alone, index-matched, isotropic, mean free path 10 mm)
    against Mitsuba's volumetric path tracer of the medium of the same broad-light
    albedo: two seeds of 1024 spp, whose difference gives Mitsuba's own noise. Also the
    dipole alone (the same material scattering forward, g = 0.99: no single scattering),
    to show what the single-scattering term brings."""
    import dataclasses

    from acquire.render.mitsuba_reference import agreement, corner_scene, render_reference
    from acquire.render.renderer import render

    print("   subsurface: the dipole and single scattering against the volumetric transport "
          "they approximate (Mitsuba volpath, 2 x 1024 spp)")
    print("   | light | vs Mitsuba: tone-mapped, linear | Mitsuba's noise | beyond noise | "
          "Mitsuba / ours, mean R G B | dipole alone: tone-mapped |")
    print("   |---|---|---|---|---|---|")
    worst = 0.0
    for light in ("point", "projector"):
        scene, cam = corner_scene("subsurface 10mm", light=light)
        ours = render(scene, cam, supersample=4)
        runs = [render_reference(scene, cam, spp=1024, seed=k) for k in (0, 1)]
        ref = np.mean(runs, axis=0)
        ids = ours.object_id
        a = agreement(ours.radiance, ref, ids)
        noise = agreement(runs[0], runs[1], ids).relative_l1 / 2.0
        beyond = max(a.relative_l1 - noise, 0.0)
        worst = max(worst, beyond)
        m = ids == 2
        ratio = ref[m].mean(0) / ours.radiance[m].mean(0)
        ball = scene.objects[0]
        scene.objects[0] = dataclasses.replace(
            ball, material=dataclasses.replace(ball.material, anisotropy=0.99))
        alone = agreement(render(scene, cam, supersample=4).radiance, ref, ids).relative_l1
        print(f"   | {light} | {100 * a.relative_l1:.2f} %, {100 * a.relative_l1_linear:.2f} % "
              f"| {100 * noise:.2f} % | {100 * beyond:.2f} % | "
              f"{' '.join(f'{r:.3f}' for r in ratio)} | {100 * alone:.2f} % |", flush=True)
        panels.append((f"{light}, subsurface 10 mm", ours.radiance, ref))
    print(f"   worst subsurface error beyond Mitsuba's noise: {100 * worst:.2f} % (target "
          f"<= 3 %) {'PASS' if worst <= 0.03 else 'MISS'}; what is left: transport that "
          f"a diffusion profile spread in the image does not express (docs/materials.md)")


if __name__ == "__main__":
    sys.exit(main())
