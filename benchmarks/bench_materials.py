"""Material effects on a laser scanner (issue 17), measured on a flat plate
(data_synth.plates): the inward depth bias and the widening of the stripe on a
subsurface material against the mean free path and the incidence (triangulation angle
fixed at 60 degrees), by peak detector; the diffusion alone (the material scattering
almost only forward, g = 0.99, so nothing is scattered once) against the closed form of
the shifted-source model; and a polished metal plate's highlight and dropout. Writes
docs/img/material_effects.png."""

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def _frame(material, inc, view):
    from acquire.laser.sheet import LaserRenderer
    from data_synth.plates import laser_plate

    lp = laser_plate(material, incidence_deg=inc, view_deg=view)
    fr = LaserRenderer(lp.scene, lp.camera).frame(lp.camera.cam_from_world, lp.laser)
    return lp, fr.radiance.astype(np.float64)


def main():
    from acquire.render.materials import Material
    from reconstruct.laser.stripe import DETECTORS, StripeOptions, detect_peaks

    white = np.array([0.9, 0.9, 0.9])
    dets = [d for d in DETECTORS if d != "argmax"]
    print("   subsurface plate, albedo 0.9, ior 1.5; laser sigma 0.3 mm, 0.3 m away; "
          "triangulation angle 60 deg = incidence + view")
    print("   | mfp mm | incidence deg | depth bias mm by " + ", ".join(dets)
          + " (- : no peak found) | stripe FWHM px | diffusion alone, gaussian | "
          "closed form mm |")
    print("   |---|---|---|---|---|---|")

    def biases(img, lp, methods):
        scaled = img * 200 / img.max()
        out = []
        for d in methods:
            cols, _ = detect_peaks(scaled, options=StripeOptions(
                method=d, max_width=60, threshold=5, min_contrast=3))
            z = lp.triangulate(cols)[:, 2]
            out.append(float(np.median(z[np.isfinite(z)])) * 1e3 if np.isfinite(z).any()
                       else float("nan"))
        return out

    rows, profiles = [], {}
    for mfp in (0.0, 0.1e-3, 0.3e-3, 1e-3, 3e-3):
        for inc in (0.0, 15.0, 30.0, 45.0):
            view = 60.0 - inc
            mat = (Material(albedo=white) if mfp == 0 else
                   Material(albedo=white, brdf="subsurface", mfp=mfp))
            lp, img = _frame(mat, inc, view)
            bias = biases(img, lp, dets)
            alone = (bias[dets.index("gaussian")] if mfp == 0 else biases(_frame(
                Material(albedo=white, brdf="subsurface", mfp=mfp, anisotropy=0.99),
                inc, view)[1], lp, ["gaussian"])[0])
            ti, tv = np.radians(inc), np.radians(view)
            want = -mfp * 1e3 * np.sin(ti) / 1.5 * np.cos(ti) * np.cos(tv) / np.sin(ti + tv)
            row = img[len(img) // 2]
            fwhm = int((row > 0.5 * row.max()).sum())
            rows.append((mfp, inc, bias, alone, want, fwhm))
            if inc == 30.0:
                profiles[mfp] = row / row.max()
            print(f"   | {mfp * 1e3:g} | {inc:g} | "
                  + ", ".join("-" if np.isnan(b) else f"{b:+.3f}" for b in bias)
                  + f" | {fwhm} | {alone:+.3f} | {want:+.3f} |", flush=True)
    worst = max(abs(alone - want) for *_, alone, want, _ in rows)
    print(f"   worst |diffusion alone - closed form|: {worst:.3f} mm (a check of the "
          f"rendering and triangulation chain)")
    metal = Material(albedo=np.ones(3), brdf="conductor", roughness=0.15)
    matte = Material(albedo=np.ones(3))
    for view in (30.0, 20.0, 5.0):
        a = _frame(metal, 30.0, view)[1].max()
        b = _frame(matte, 30.0, view)[1].max()
        print(f"   polished metal (r 0.15) vs matte, incidence 30, view {view:g} deg "
              f"({'mirror' if view == 30 else 'off mirror'}): peak radiance "
              f"{a / b:.2f}x the matte plate's")
    groove = _groove()
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 3, figsize=(14, 3.4))
    for mfp, prof in profiles.items():
        ax[0].plot(prof, label="matte" if mfp == 0 else f"mfp {mfp * 1e3:g} mm")
    c = int(np.argmax(profiles[0.0]))
    ax[0].set_xlim(c - 40, c + 40)
    ax[0].set_xlabel("column (px)")
    ax[0].set_ylabel("stripe radiance / peak")
    ax[0].set_title("one image row across the stripe (incidence 30 deg)", fontsize=9)
    ax[0].legend(fontsize=7)
    for mfp in (0.1e-3, 0.3e-3, 1e-3, 3e-3):
        sel = [r for r in rows if r[0] == mfp]
        ax[1].plot([r[1] for r in sel], [r[2][1] for r in sel], "o-",
                   label=f"mfp {mfp * 1e3:g} mm")
        ax[1].plot([r[1] for r in sel], [r[4] for r in sel], "k:", lw=0.8)
    ax[1].set_xlabel("incidence (deg), triangulation angle 60 deg")
    ax[1].set_ylabel("depth bias (mm), gaussian detector")
    ax[1].set_title("measured, g = 0.8 (dots); the diffusion's closed form (dotted)",
                    fontsize=9)
    ax[1].legend(fontsize=7)
    for label, rates in groove.items():
        ax[2].plot(np.arange(len(rates)), 100 * rates, "o-", label=label)
    ax[2].set_xlabel("Gray-code bit (0 = coarsest: 512 px stripes; 8 = 2 px)")
    ax[2].set_ylabel("bit errors off the stripe edges (%)")
    ax[2].set_title("structured light in a 50-degree groove, one bounce", fontsize=9)
    ax[2].legend(fontsize=7)
    fig.tight_layout()
    out = ROOT / "docs" / "img" / "material_effects.png"
    fig.savefig(out, dpi=110)
    print(f"   wrote {out.relative_to(ROOT)}")
    return 0


class _Ideal:
    def apply(self, img, rng):
        return img


def _groove() -> dict:
    """Structured light (the SL rig's Gray code) on a concave groove with one bounce:
    where the decoding errs and which patterns err (Gupta and Nayar)."""
    from acquire.render.materials import Material
    from acquire.render.projector import PatternProjector
    from acquire.stereo.capture_sl import _render_patterns
    from acquire.stereo.patterns import gray_code_bits, gray_code_patterns
    from acquire.stereo.rig import RigConfig
    from data_synth.plates import v_groove
    from reconstruct.stereo.structured_light import decode_gray_code, gray_bit_errors

    cam, pcam = RigConfig().sl_devices()
    nc, _ = gray_code_bits(pcam.width, pcam.height)
    pats = gray_code_patterns(pcam.width, pcam.height)[: 2 * nc]
    proj = PatternProjector(pcam, pats[0], 0.12)
    print("   structured light, Gray code, 50-degree groove, albedo 0.95, noiseless sensor")
    print("   | surface | bounces | columns wrong | within 2 cm of the crease | farther |")
    print("   |---|---|---|---|---|")
    rates = {}
    for name, mat in (("matte", Material(albedo=np.full(3, 0.95))),
                      ("glossy coat r0.6", Material(albedo=np.full(3, 0.95), brdf="dielectric",
                                                    roughness=0.6))):
        for bounces in (0, 1):
            imgs, depth = _render_patterns(v_groove(mat, opening_deg=50.0), cam, proj, pats,
                                           _Ideal(), np.random.default_rng(0), supersample=2,
                                           ambient=0.0, bounces=bounces)
            m = depth > 0
            yy, xx = np.nonzero(m)
            pts = cam.unproject(np.stack([xx, yy], 1).astype(float), depth[m].astype(float))
            col = np.round(pcam.project(pts)[0][:, 0]).astype(np.int64)
            true = np.full(depth.shape, -1, np.int64)
            true[yy, xx] = np.where((col >= 0) & (col < pcam.width), col, -1)
            dec, _, _ = decode_gray_code(imgs, n_col_bits=nc, n_row_bits=0,
                                         min_bit_contrast=0.0)
            wrong = (true >= 0) & (np.abs(dec - true) > 1)
            xw = np.full(depth.shape, np.nan)
            xw[yy, xx] = pts[:, 0]
            near = (true >= 0) & (np.abs(xw) < 0.02)
            far = (true >= 0) & (np.abs(xw) >= 0.02)
            print(f"   | {name} | {bounces} | {100 * wrong[true >= 0].mean():.2f} % | "
                  f"{100 * wrong[near].mean():.2f} % | {100 * wrong[far].mean():.2f} % |")
            if bounces:
                rates[name] = gray_bit_errors(imgs, true, n_bits=nc)[:-1]
                print(f"   {name}, bit error rates (coarsest first): "
                      + ", ".join(f"{100 * r:.2f}" for r in rates[name]) + " %")
    return rates


if __name__ == "__main__":
    sys.exit(main())
