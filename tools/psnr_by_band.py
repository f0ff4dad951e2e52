#!/usr/bin/env python3
"""Where on a test set's reference frame a method gains or loses: PSNR-T and the median ratio
of the output to the ground truth per band of the reference frame's code.

For one Kalantari-layout set (SET/frame_*.tif, SET/exposure.txt, SET/HDRImg.hdr) and the
outputs `hdrsynth eval` wrote for it (EVAL/<set>.exr, one folder per method), prints per band of
the reference frame's largest channel code (the middle input, as the networks take it): the
share of pixels, and per method PSNR-T (μ-law, μ = 5000, over the band's pixels, as the
product's metrics compute it) and median(output / ground truth). The outputs are written in the
reference frame's units (HDR = LDR^γ / 2^s with s its exposure.txt value); they are scaled by
2^−s back to the ground truth's.

A band where the copy's ratio is far from 1 while the triangle merge's is near 1 is one where
the reference frame's linearised value disagrees with the other frames.

Run: tools/psnr_by_band.py SET NAME=EVAL_DIR [NAME=EVAL_DIR ...]
Needs numpy, OpenEXR, opencv-python-headless.
"""

import math
import sys
from pathlib import Path

import cv2
import Imath
import numpy as np
import OpenEXR

BANDS = [(0.0, 0.02), (0.02, 0.05), (0.05, 0.1), (0.1, 0.3), (0.3, 0.9), (0.9, 1.01)]


def read_exr(path: Path) -> np.ndarray:
    f = OpenEXR.InputFile(str(path))
    dw = f.header()["dataWindow"]
    w, h = dw.max.x - dw.min.x + 1, dw.max.y - dw.min.y + 1
    pt = Imath.PixelType(Imath.PixelType.FLOAT)
    return np.stack([np.frombuffer(f.channel(c, pt), np.float32).reshape(h, w)
                     for c in "RGB"], -1).astype(np.float64)


def mu(x: np.ndarray) -> np.ndarray:
    return np.log1p(5000.0 * x) / math.log1p(5000.0)


def main() -> None:
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    s = Path(sys.argv[1])
    frames = sorted(s.glob("frame_*.tif"))
    evs = [float(v) for v in (s / "exposure.txt").read_text().split()]
    mid = len(frames) // 2
    ref = cv2.imread(str(frames[mid]), cv2.IMREAD_UNCHANGED)[..., ::-1]
    ref = ref / (65535.0 if ref.dtype == np.uint16 else 255.0)
    gt = cv2.imread(str(s / "HDRImg.hdr"), cv2.IMREAD_UNCHANGED)[..., ::-1].astype(np.float64)
    outs = {}
    for arg in sys.argv[2:]:
        name, folder = arg.split("=", 1)
        outs[name] = read_exr(Path(folder) / f"{s.name}.exr") * 2.0 ** -evs[mid]
    code = np.repeat(ref.max(-1, keepdims=True), 3, -1)
    print(f"{s}: reference frame {frames[mid].name} (exposure.txt {evs[mid]:g})")
    print("band | share | " + " | ".join(f"{n} PSNR-T, ratio" for n in outs))
    for lo, hi in BANDS:
        m = (code >= lo) & (code < hi)
        if not m.any():
            continue
        cells = []
        for o in outs.values():
            mse = np.mean((mu(o[m]) - mu(gt[m])) ** 2)
            ratio = np.median(o[m] / np.maximum(gt[m], 1e-6))
            cells.append(f"{10 * math.log10(1 / mse):.1f}, {ratio:.2f}")
        print(f"{lo:g}–{hi:g} | {m.mean():.3f} | " + " | ".join(cells))


if __name__ == "__main__":
    main()
