#!/usr/bin/env python3
"""Dev-time generator of tests/data/oracle_crops/ (never a runtime dependency).

Small reference data that the tests use without ../shared/data: crops of two real HDR scenes
(openexr-images, BSD-3), 8-bit brackets made from them, and the outputs of OpenCV MergeMertens,
a numpy triangle merge, scikit-image PSNR/SSIM (plus the PU21 numpy transcription of
tools/metrics_reference.py), colour-science CIEDE2000 and colour-science colour correction;
then OpenCV MergeDebevec and MergeRobertson on the three-frame PNGs (tools/debevec_oracle.py,
tools/robertson_oracle.py, `add_cases`).
Conventions are those of ../shared/data/oracles/oracles.json; PROVENANCE.md in the output
folder lists them with the tool versions. Deterministic: the crop windows are chosen by a fixed
score, the noise and the random pairs come from fixed seeds.

    python3 -m venv /tmp/cropsenv
    /tmp/cropsenv/bin/pip install opencv-python-headless scikit-image colour-science numpy OpenEXR
    /tmp/cropsenv/bin/python tools/oracle_crops.py [../shared/data] [tests/data/oracle_crops]
"""
import csv
import json
import os
import sys
from importlib.metadata import version

import cv2
import numpy as np
import OpenEXR

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import metrics_reference  # noqa: E402  (PU21 transcription and the field's PSNR/SSIM calls)

import colour  # noqa: E402
import debevec_oracle  # noqa: E402  (the MergeDebevec cases, added to oracles.json at the end)
from debevec_oracle import write_exr  # noqa: E402  (one EXR writer for every oracle output)
import robertson_oracle  # noqa: E402  (the MergeRobertson cases, likewise)

# (name in the output, source file in ../shared/data/real_hdr)
SCENES = [("desk", "Desk.exr"), ("carrots", "Carrots.exr")]
CROP_W, CROP_H = 64, 48
STRIDE = 8
GAMMA = 2.2
THREE = ("3exp", [-2, 0, 2])
TWO = ("2exp", [-3, 0])
METRIC_PEAK = 1.5  # the metric ground truth is clipped to [0, 1.5], as the full-size cases
METRIC_P99 = 0.85  # ... after scaling the crop's 99th percentile to this value
NOISE_SIGMA = 0.01
GAIN = 1.07
BLUR_SIGMA = 1.2
SEED = 20261127


def read_radiance(path):
    with OpenEXR.File(path) as f:
        ch = f.channels()
        key = "RGBA" if "RGBA" in ch else "RGB"
        a = ch[key].pixels[..., :3]
    return np.asarray(a, dtype=np.float64)


def read_exr(path):
    return metrics_reference.read_exr(path)


def write_png(path, rgb8):
    assert cv2.imwrite(path, np.ascontiguousarray(rgb8[..., ::-1])), path


def read_png_bgr(path):
    im = cv2.imread(path, cv2.IMREAD_UNCHANGED)
    assert im is not None and im.dtype == np.uint8 and im.shape[2] == 3, path
    return im


def choose_crop(rad):
    """The CROP_W x CROP_H window (stride STRIDE, raster order, first wins ties) with the widest
    luminance range in stops between its 1st and 99th percentiles, among windows whose median
    luminance lies within 2 stops of the whole image's (so the brackets keep mid-tones)."""
    y = np.maximum(rad @ np.array([0.2126, 0.7152, 0.0722]), 1e-6)
    med_all = np.median(y)
    best = None
    for y0 in range(0, rad.shape[0] - CROP_H + 1, STRIDE):
        for x0 in range(0, rad.shape[1] - CROP_W + 1, STRIDE):
            w = y[y0:y0 + CROP_H, x0:x0 + CROP_W]
            if abs(np.log2(np.median(w) / med_all)) > 2:
                continue
            lo, hi = np.percentile(w, [1, 99])
            stops = np.log2(hi / lo)
            if best is None or stops > best[0]:
                best = (stops, x0, y0)
    return best


def bracket(rad, k, ev):
    """round(255 * clip(radiance * k * 2^EV, 0, 1)^(1/2.2)), 8-bit."""
    v = np.clip(rad * k * 2.0 ** ev, 0.0, 1.0) ** (1.0 / GAMMA)
    return np.round(255.0 * v).astype(np.uint8)


def triangle_merge(frames_rgb8, times):
    """LDR/255, H_i = L_i^2.2 / t_i; weights of the middle frame's value I per channel:
    low = max(0, I - .5)/.5, mid = I/.5 if I < .5 else (1 - I)/.5, high = max(0, .5 - I)/.5."""
    ldr = [f.astype(np.float64) / 255.0 for f in frames_rgb8]
    h = [l ** GAMMA / t for l, t in zip(ldr, times)]
    i = ldr[1]
    w = [np.maximum(0, i - 0.5) / 0.5, np.where(i < 0.5, i / 0.5, (1 - i) / 0.5),
         np.maximum(0, 0.5 - i) / 0.5]
    num = sum(wk * hk for wk, hk in zip(w, h))
    den = sum(w)
    return num / den


def main():
    shared = sys.argv[1] if len(sys.argv) > 1 else os.path.join(HERE, "../../shared/data")
    out = sys.argv[2] if len(sys.argv) > 2 else os.path.join(HERE, "../tests/data/oracle_crops")
    os.makedirs(out, exist_ok=True)
    rng = np.random.default_rng(SEED)
    cases, metric_cases, crops = {}, {}, {}
    for name, src in SCENES:
        rad = read_radiance(os.path.join(shared, "real_hdr", src))
        stops, x0, y0 = choose_crop(rad)
        crop = np.maximum(rad[y0:y0 + CROP_H, x0:x0 + CROP_W], 0.0)
        k = 0.5 / np.median(crop)
        crops[name] = dict(source=f"real_hdr/{src}", x=x0, y=y0, width=CROP_W, height=CROP_H,
                           stops_p1_p99=round(float(stops), 3), k=float(k))
        written = {}
        for tag, evs in (THREE, TWO):
            files = []
            for ev in evs:
                f = f"{name}_ev{ev:+d}.png"
                if f not in written:
                    write_png(os.path.join(out, f), bracket(crop, k, ev))
                    written[f] = True
                files.append(f)
            bgr = [read_png_bgr(os.path.join(out, f)) for f in files]
            for suffix, e in (("mertens_default", 0.0), ("mertens_cse", 1.0)):
                case = f"{name}_{tag}_{suffix}"
                fused = cv2.createMergeMertens(1.0, 1.0, e).process(bgr)[..., ::-1]
                write_exr(os.path.join(out, f"{case}.exr"), fused)
                cases[case] = dict(kind="mertens", inputs=files, contrast_weight=1.0,
                                   saturation_weight=1.0, exposure_weight=e,
                                   output=f"{case}.exr")
            if tag == "3exp":
                times = [2.0 ** ev for ev in evs]
                rgb = [b[..., ::-1] for b in bgr]
                case = f"{name}_3exp_triangle"
                write_exr(os.path.join(out, f"{case}.exr"), triangle_merge(rgb, times))
                cases[case] = dict(kind="triangle_merge", inputs=files, exposure_times=times,
                                   gamma=GAMMA, output=f"{case}.exr")
        # Metric pairs: the ground truth and three predictions, read back from their files.
        s = METRIC_P99 / np.percentile(crop, 99)
        gt = np.clip(crop * s, 0.0, METRIC_PEAK).astype(np.float32)
        preds = {
            "noise": np.maximum(gt + rng.normal(0.0, NOISE_SIGMA, gt.shape), 0.0),
            "gain": gt * np.float32(GAIN),
            "blur": cv2.GaussianBlur(gt, (0, 0), BLUR_SIGMA),
        }
        write_exr(os.path.join(out, f"{name}_metric_gt.exr"), gt)
        for p, img in preds.items():
            write_exr(os.path.join(out, f"{name}_metric_pred_{p}.exr"), img)
        g = read_exr(os.path.join(out, f"{name}_metric_gt.exr"))
        for p in preds:
            pf = f"{name}_metric_pred_{p}.exr"
            pr = read_exr(os.path.join(out, pf))
            m = metrics_reference.field_metrics(g, pr)
            pu_psnr, pu_ssim = metrics_reference.pu21_metrics(g, pr)
            metric_cases[f"{name}_{p}"] = dict(
                gt=f"{name}_metric_gt.exr", pred=pf, **{k2: float(v) for k2, v in m.items()},
                pu21_psnr=pu_psnr, pu21_ssim=pu_ssim)

    # CIEDE2000 on 40 random Lab pairs (L in [0, 100], a and b in [-80, 80]).
    lab = np.column_stack([rng.uniform(0, 100, 80), rng.uniform(-80, 80, (80, 2))])
    lab1, lab2 = lab[:40], lab[40:]
    de = colour.delta_E(lab1, lab2, method="CIE 2000")
    delta_e = [dict(lab1=a.tolist(), lab2=b.tolist(), de00=float(d))
               for a, b, d in zip(lab1, lab2, de)]

    # Colour correction: the ColorChecker24 linear sRGB values (synthetic) and a simulated camera
    # response to them (real): a fixed 3x3 mix, root-polynomial cross terms and seeded noise.
    with open(os.path.join(shared, "colorchecker24.csv")) as f:
        syn = np.array([[float(r[c]) for c in ("R_lin_sRGB_D65", "G_lin_sRGB_D65",
                                                  "B_lin_sRGB_D65")] for r in csv.DictReader(f)])
    mix = np.array([[0.80, 0.24, -0.04], [0.06, 0.88, 0.06], [0.02, -0.16, 1.14],
                    [0.03, -0.02, 0.01], [0.01, 0.02, -0.03], [-0.01, 0.00, 0.02]]).T
    expanded = colour.characterisation.polynomial_expansion_Finlayson2015(syn, degree=2)
    real = expanded @ mix.T + rng.normal(0.0, 0.005, syn.shape)
    t = colour.characterisation.matrix_colour_correction(syn, real, method="Finlayson 2015",
                                                         degree=1)
    rp = colour.characterisation.matrix_colour_correction(syn, real, method="Finlayson 2015",
                                                          degree=2)

    tools = {p: version(p) for p in ("opencv-python-headless", "scikit-image", "colour-science",
                                     "numpy", "scipy", "OpenEXR")}
    doc = dict(
        about="Oracle outputs on crops of real HDR scenes; written by tools/oracle_crops.py "
              "(PROVENANCE.md beside this file).",
        tools=tools,
        crops=crops,
        cases=cases,
        metrics=dict(
            convention="PSNR: skimage peak_signal_noise_ratio(gt, pred, data_range=1.0) on "
                       "linear (L) and on mu-law tonemapped log(1+5000x)/log(5001) (T) images, "
                       "no clipping before PSNR. SSIM: both images clip(x*255, 0, 255), skimage "
                       "structural_similarity(channel_axis=-1, gaussian_weights=True, sigma=1.5, "
                       "use_sample_covariance=False, data_range=255). PU21 (ReferenceMax, peak "
                       "4000): tools/metrics_reference.py pu21_metrics. Images read back from "
                       "the EXR files (float32).",
            cases=metric_cases),
        delta_e_2000=delta_e,
        colour_correction=dict(
            synthetic_rgb=syn.tolist(), real_rgb=real.tolist(),
            T_least_squares_3x3=t.tolist(), root_polynomial_degree2_matrix=rp.tolist(),
            note="real = T . synthetic, colour.characterisation.matrix_colour_correction("
                 "synthetic, real, method='Finlayson 2015', degree=1 or 2)"),
    )
    with open(os.path.join(out, "oracles.json"), "w") as f:
        json.dump(doc, f, indent=1)
        f.write("\n")
    debevec_oracle.add_cases(out)
    robertson_oracle.add_cases(out)
    print(json.dumps(dict(tools=tools, crops=crops), indent=1))


if __name__ == "__main__":
    main()
