#!/usr/bin/env python3
"""Dev-time check of a loop's ground truth, and of its rows, against the true radiance of a
generated bracket (tools/generated_bracket.sh): never a runtime dependency.

    python3 -m venv /tmp/gtenv
    /tmp/gtenv/bin/pip install opencv-python-headless numpy OpenEXR
    /tmp/gtenv/bin/python tools/ground_truth_vs_radiance.py LOOP_OUT RADIANCE_DIR

LOOP_OUT is `hdrsynth loop`'s --out on the generated folder, RADIANCE_DIR the linear EXRs the
folder was rendered from (scene_NN is the NN-th EXR in name order). Per test scene the true
radiance is scaled to the ground truth's unit by one factor, the median ratio over pixels whose
ground truth lies in 0.02–0.5 of the reference's white (the estimated response is known up to
scale only). Printed: the ground truth's μ-law squared error (×1e3) and mean ln ratio against
the radiance per radiance bin, its PSNR-T against the radiance with values above the shortest
frame's white capped (3.5 of the reference's white for "0 2 4"), and every row's mean PSNR-T
(seeds and scenes) against the ground truth and against the radiance.
"""
import glob
import os
import sys

os.environ["OPENCV_IO_ENABLE_OPENEXR"] = "1"
import cv2  # noqa: E402
import numpy as np  # noqa: E402
import OpenEXR  # noqa: E402

MU = 5000.0
BINS = [0, 1e-4, 1e-3, 1e-2, 1e-1, 1, 3.5, 1e9]


def tone(x):
    return np.log1p(MU * np.maximum(x, 0)) / np.log1p(MU)


def psnr(a, b):
    return 10 * np.log10(1.0 / np.mean((a - b) ** 2))


def read(path):
    if path.endswith(".exr"):
        return OpenEXR.File(path).channels()["RGB"].pixels.astype(np.float64)
    return cv2.imread(path, cv2.IMREAD_UNCHANGED)[..., ::-1].astype(np.float64)


def main(loop, radiance_dir):
    ts = os.path.join(loop, "testset")
    sets = sorted(d for d in os.listdir(ts) if os.path.isdir(os.path.join(ts, d)))
    radiance = sorted(glob.glob(os.path.join(radiance_dir, "*.exr")))
    gts, truths = {}, {}
    for s in sets:
        stops = [float(v) for v in open(os.path.join(ts, s, "exposure.txt")).read().split()]
        # hdrsynth's unit: 1 = the reference's white (the file's unit is the shortest input's).
        gt = read(os.path.join(ts, s, "HDRImg.hdr")) * 2 ** (stops[1] - stops[0])
        r = read(radiance[int(s.split("_")[1])])
        m = (gt > 0.02) & (gt < 0.5) & (r > 0)
        gts[s], truths[s] = gt, r * np.median(gt[m] / r[m])
    se, n, ln = (np.zeros(len(BINS) - 1) for _ in range(3))
    for s in sets:
        g, t = gts[s], truths[s]
        e = (tone(g) - tone(t)) ** 2
        for i in range(len(BINS) - 1):
            m = (t >= BINS[i]) & (t < BINS[i + 1])
            se[i] += e[m].sum()
            n[i] += m.sum()
            ln[i] += np.log(np.maximum(g[m], 1e-9) / t[m]).sum()
    print("radiance bins (reference white = 1):", BINS)
    print("pixel share:      ", " ".join(f"{v:.3f}" for v in n / n.sum()))
    print("GT μ-law SE ×1e3: ", " ".join(f"{a / max(b, 1) * 1e3:.4f}" for a, b in zip(se, n)))
    print("GT mean ln ratio: ", " ".join(f"{a / max(b, 1):+.3f}" for a, b in zip(ln, n)))
    capped = [psnr(tone(np.minimum(gts[s], 3.5)), tone(np.minimum(truths[s], 3.5))) for s in sets]
    print(f"GT PSNR-T against the radiance (capped at 3.5): {np.mean(capped):.2f} dB")
    cells = os.path.join(loop, "experiment", "cells")
    print(f"{'row':<12} {'vs GT':>7} {'vs radiance':>12}")
    for cell in sorted(os.listdir(cells)):
        dirs = sorted(glob.glob(os.path.join(cells, cell, "seed*", "eval")))
        dirs = dirs or [os.path.join(cells, cell, "eval")]
        a, b = [], []
        for d in dirs:
            for s in sets:
                p = tone(read(os.path.join(d, s + ".exr")))
                a.append(psnr(p, tone(gts[s])))
                b.append(psnr(p, tone(truths[s])))
        print(f"{cell:<12} {np.mean(a):7.2f} {np.mean(b):12.2f}")


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2])
