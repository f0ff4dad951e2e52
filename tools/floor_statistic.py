#!/usr/bin/env python3
"""The device-output check's floor statistic on a folder of one bracket, read independently of
hdrsynth with NumPy: frames declared sRGB, exposure times from EXIF. For each frame, each value
that a frame exposed at least twice as long holds at codes 26-230 (the shortest such frame) is
predicted at the shorter exposure through sRGB; where the prediction lies at codes 4-16, the
frame's own code is compared with it. Prints the mean (code - predicted) x 255 per frame and
pooled. The same statistic as `hdrsynth diagnose --brackets DIR --profile P --device-output`
with P from `calibrate brackets --response srgb` (docs/experiments.md).

usage: tools/floor_statistic.py DIR"""
import pathlib
import sys

import numpy as np
from PIL import Image

EXIF_IFD, EXPOSURE_TIME = 0x8769, 0x829A


def srgb_decode(c):
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def srgb_encode(x):
    x = np.maximum(x, 0.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055)


def main(folder):
    files = sorted(p for p in pathlib.Path(folder).iterdir() if p.suffix.lower() in (".jpg", ".jpeg"))
    frames, times = [], []
    for p in files:
        img = Image.open(p)
        times.append(float(img.getexif().get_ifd(EXIF_IFD)[EXPOSURE_TIME]))
        frames.append(np.asarray(img.convert("RGB"), dtype=np.float64) / 255.0)
    total = [0.0, 0.0, 0]
    for i, frame in enumerate(frames):
        longer = sorted((j for j in range(len(frames)) if times[j] >= 2 * times[i]), key=lambda j: times[j])
        pred = np.full(frame.shape, np.nan)
        for j in longer:
            c = frames[j]
            m = (c >= 26 / 255) & (c <= 230 / 255) & np.isnan(pred)
            pred[m] = srgb_encode(srgb_decode(c[m]) * times[i] / times[j])
        sel = (pred >= 4 / 255) & (pred < 16 / 255)
        if sel.any():
            print(f"{files[i].name}: {sel.sum()} values, code {255 * frame[sel].mean():.2f}, predicted {255 * pred[sel].mean():.2f}")
        total[0] += frame[sel].sum()
        total[1] += pred[sel].sum()
        total[2] += int(sel.sum())
    print(f"floor statistic: {255 * (total[0] - total[1]) / max(total[2], 1):+.2f} over {total[2]} values")


if __name__ == "__main__":
    main(sys.argv[1])
