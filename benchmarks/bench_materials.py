"""Material effects on a laser scanner (issue 17), measured on a flat plate
(data_synth.plates): the inward depth bias and the widening of the stripe on a
subsurface material against the mean free path and the incidence (triangulation angle
fixed at 60 degrees), by peak detector, against the closed form of the shifted-source
model; and a polished metal plate's highlight and dropout. Writes
docs/img/subsurface_stripe.png."""

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def _frame(material, inc, view):
    from acquire.laser import LaserRenderer
    from data_synth.plates import laser_plate

    lp = laser_plate(material, incidence_deg=inc, view_deg=view)
    fr = LaserRenderer(lp.scene, lp.camera).frame(lp.camera.cam_from_world, lp.laser)
    return lp, fr.radiance.astype(np.float64)


def main():
    from acquire.materials import Material
    from reconstruct.stripe import DETECTORS, StripeOptions, detect_peaks

    white = np.array([0.9, 0.9, 0.9])
    dets = [d for d in DETECTORS if d != "argmax"]
    print("   subsurface plate, albedo 0.9, ior 1.5; laser sigma 0.3 mm, 0.3 m away; "
          "triangulation angle 60 deg = incidence + view")
    print("   | mfp mm | incidence deg | depth bias mm by " + ", ".join(dets)
          + " | closed form mm | stripe FWHM px |")
    print("   |---|---|---|---|---|")
    rows, profiles = [], {}
    for mfp in (0.0, 0.1e-3, 0.3e-3, 1e-3, 3e-3):
        for inc in (0.0, 15.0, 30.0, 45.0):
            view = 60.0 - inc
            mat = (Material(albedo=white) if mfp == 0 else
                   Material(albedo=white, brdf="subsurface", mfp=mfp))
            lp, img = _frame(mat, inc, view)
            scaled = img * 200 / img.max()
            bias = []
            for d in dets:
                cols, _ = detect_peaks(scaled, options=StripeOptions(
                    method=d, max_width=60, threshold=5, min_contrast=3))
                bias.append(float(np.nanmedian(lp.triangulate(cols)[:, 2])) * 1e3)
            ti, tv = np.radians(inc), np.radians(view)
            want = -mfp * 1e3 * np.sin(ti) / 1.5 * np.cos(ti) * np.cos(tv) / np.sin(ti + tv)
            row = img[len(img) // 2]
            fwhm = int((row > 0.5 * row.max()).sum())
            rows.append((mfp, inc, bias, want, fwhm))
            if inc == 30.0:
                profiles[mfp] = row / row.max()
            print(f"   | {mfp * 1e3:g} | {inc:g} | " + ", ".join(f"{b:+.3f}" for b in bias)
                  + f" | {want:+.3f} | {fwhm} |", flush=True)
    worst = max(abs(b - want) for *_, bias, want, _ in rows for b in bias)
    print(f"   worst |measured - closed form| over detectors: {worst:.3f} mm")
    metal = Material(albedo=np.ones(3), brdf="conductor", roughness=0.15)
    matte = Material(albedo=np.ones(3))
    for view in (30.0, 20.0, 5.0):
        a = _frame(metal, 30.0, view)[1].max()
        b = _frame(matte, 30.0, view)[1].max()
        print(f"   polished metal (r 0.15) vs matte, incidence 30, view {view:g} deg "
              f"({'mirror' if view == 30 else 'off mirror'}): peak radiance "
              f"{a / b:.2f}x the matte plate's")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 2, figsize=(10, 3.4))
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
        ax[1].plot([r[1] for r in sel], [r[3] for r in sel], "k:", lw=0.8)
    ax[1].set_xlabel("incidence (deg), triangulation angle 60 deg")
    ax[1].set_ylabel("depth bias (mm), gaussian detector")
    ax[1].set_title("measured (dots) and closed form (dotted)", fontsize=9)
    ax[1].legend(fontsize=7)
    fig.tight_layout()
    out = ROOT / "docs" / "img" / "subsurface_stripe.png"
    fig.savefig(out, dpi=110)
    print(f"   wrote {out.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
