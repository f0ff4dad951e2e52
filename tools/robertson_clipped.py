#!/usr/bin/env python3
"""How much of the Robertson row's deficit is the pixels OpenCV's recipe sets to 0.

OpenCV's MergeRobertson weights a code with a Gaussian that is exactly 0 at 0 and 255, so a
pixel clipped in every frame merges to 0 (black) where the scene is brightest. For a finished
main job's folder QS, per ISO of the primary test set: the share of pixels the Robertson row
gives 0 where the ground truth is above 0.5, its mean PSNR-T as scored, and its mean PSNR-T
with those pixels taken from the triangle row (PSNR-T as the product computes it: μ-law
T(x) = ln(1 + 5000x) / ln(5001), no clipping, MSE over pixels and channels).

Run: python3 tools/robertson_clipped.py QS [--seed 1]   (numpy, OpenEXR)
"""

import argparse
import glob
import statistics
from pathlib import Path

import numpy as np
import OpenEXR


def read(path: str) -> np.ndarray:
    ch = OpenEXR.File(path).channels()
    if "RGB" in ch:
        return np.asarray(ch["RGB"].pixels, dtype=np.float64)
    return np.stack([np.asarray(ch[c].pixels, dtype=np.float64) for c in "RGB"], -1)


def psnr_t(a: np.ndarray, b: np.ndarray) -> float:
    t = lambda x: np.log1p(5000.0 * np.maximum(x, 0.0)) / np.log(5001.0)
    return float(10.0 * np.log10(1.0 / np.mean((t(a) - t(b)) ** 2)))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("qs", type=Path)
    ap.add_argument("--seed", type=int, default=1)
    a = ap.parse_args()
    cells = a.qs / "experiment/cells"
    print("| ISO | pixels set to 0 (ground truth > 0.5) | Robertson PSNR-T | with those pixels "
          "from the triangle merge | triangle merge |")
    print("|---|---|---|---|---|")
    for iso in (100, 800, 3200):
        share, scored, mended, tri = [], [], [], []
        pattern = str(cells / f"robertson/seed{a.seed}/eval/*_iso{iso}.exr")
        for path in sorted(glob.glob(pattern)):
            name = Path(path).stem
            rob = read(path)
            triangle = read(str(cells / f"triangle/seed{a.seed}/eval/{name}.exr"))
            gt = read(str(a.qs / f"data/testset/seed{a.seed}/{name}/hdr_gt.exr"))
            black = (rob.max(-1) <= 0.0) & (gt.max(-1) > 0.5)
            share.append(black.mean())
            scored.append(psnr_t(rob, gt))
            fixed = rob.copy()
            fixed[black] = triangle[black]
            mended.append(psnr_t(fixed, gt))
            tri.append(psnr_t(triangle, gt))
        print(f"| {iso} | {100 * statistics.fmean(share):.2f} % | {statistics.fmean(scored):.2f} | "
              f"{statistics.fmean(mended):.2f} | {statistics.fmean(tri):.2f} |")


if __name__ == "__main__":
    main()
