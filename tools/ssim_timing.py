"""Dev-time timing reference: scikit-image SSIM (the field's convention) on the same 4032x3024
pair that benches/metrics.rs times (`metrics/ssim/4032x3024`), for the ratio in BENCHMARKS.md.
Usage: python tools/ssim_timing.py [repeats]   (needs numpy + scikit-image; never a runtime dep)
"""
import sys
import time

import numpy as np
from skimage.metrics import structural_similarity


def pair(w, h):
    y, x = np.mgrid[0:h, 0:w]
    v = ((x * 7 + y * 13) % 1000).astype(np.float32) / 1000.0
    gt = np.stack([v, np.minimum(v * 0.8 + 0.1, 1.0), 1.0 - v], -1).astype(np.float32)
    e = (((x * 31 + y * 17) % 23).astype(np.float32) - 11.0) * 0.002
    pred = np.stack([np.maximum(gt[..., 0] + e, 0), gt[..., 1] * 0.98,
                     np.maximum(gt[..., 2] - e, 0)], -1).astype(np.float32)
    return gt, pred


def ssim(g, p):
    c = lambda a: np.clip(a.astype(np.float64) * 255, 0, 255)
    return structural_similarity(c(g), c(p), channel_axis=-1, gaussian_weights=True, sigma=1.5,
                                 use_sample_covariance=False, data_range=255)


def main():
    repeats = int(sys.argv[1]) if len(sys.argv) > 1 else 3
    for w, h in [(1024, 768), (4032, 3024)]:
        g, p = pair(w, h)
        times = []
        for _ in range(repeats):
            t = time.perf_counter()
            s = ssim(g, p)
            times.append(time.perf_counter() - t)
        print(f'skimage ssim {w}x{h}: {min(times):.3f} s (min of {repeats}; median '
              f'{sorted(times)[len(times) // 2]:.3f} s), value {s:.6f}')


if __name__ == '__main__':
    main()
