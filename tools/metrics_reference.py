#!/usr/bin/env python3
"""Dev-time reference values for src/eval/metrics.rs (never a runtime dependency).

Prints, for the oracle pairs in shared/data/oracles/, the skimage metrics (the field's
convention, float64) and PU21 PSNR/SSIM following gfxdisp/pu21's MATLAB pu21_metric.m:
PSNR over RGB PU values with peak 256; SSIM of PU luminance as MATLAB ssim(..., 'DynamicRange',
256) does it (11x11 Gaussian sigma 1.5, 'replicate' padding, mean over the whole map). Also prints
the PU21 encoder at a few luminances. Needs numpy, scipy, scikit-image, OpenEXR:
    python3 -m venv /tmp/skenv && /tmp/skenv/bin/pip install scikit-image OpenEXR
    /tmp/skenv/bin/python tools/metrics_reference.py [path/to/shared/data/oracles]
"""
import json
import os
import sys

import numpy as np
import OpenEXR
from scipy.ndimage import correlate1d
from skimage.metrics import peak_signal_noise_ratio, structural_similarity

# pu21_encoder.m, 'banding_glare' (the default).
PAR = [0.353487901, 0.3734658629, 8.277049286e-05, 0.9062562627, 0.09150303166, 0.9099517204,
       596.3148142]


def pu21_encode(y):
    p = PAR
    y = np.clip(y, 0.005, 10000.0)
    return p[6] * (((p[0] + p[1] * y ** p[3]) / (1 + p[2] * y ** p[3])) ** p[4] - p[5])


def matlab_ssim(a, b, dynamic_range):
    """MATLAB ssim(): imgaussfilt(sigma 1.5, FilterSize 11, 'replicate'), mean of the map."""
    x = np.arange(-5, 6)
    g = np.exp(-x * x / (2 * 1.5 ** 2))
    g /= g.sum()

    def filt(im):
        return correlate1d(correlate1d(im, g, axis=0, mode='nearest'), g, axis=1, mode='nearest')

    c1 = (0.01 * dynamic_range) ** 2
    c2 = (0.03 * dynamic_range) ** 2
    mux, muy = filt(a), filt(b)
    sx = filt(a * a) - mux * mux
    sy = filt(b * b) - muy * muy
    sxy = filt(a * b) - mux * muy
    num = (2 * mux * muy + c1) * (2 * sxy + c2)
    den = (mux * mux + muy * muy + c1) * (sx + sy + c2)
    return float((num / den).mean())


def pu21_metrics(gt, pred, peak=4000.0, reference_max=True):
    s = peak / gt.max() if reference_max else peak
    g, p = gt * s, pred * s
    psnr = 10 * np.log10(256.0 ** 2 / np.mean((pu21_encode(g) - pu21_encode(p)) ** 2))
    w = np.array([0.212656, 0.715158, 0.072186])
    ssim = matlab_ssim(pu21_encode(g @ w), pu21_encode(p @ w), 256.0)
    return float(psnr), ssim


def read_exr(path):
    with OpenEXR.File(path) as f:
        ch = f.channels()
        a = ch['RGB'].pixels if 'RGB' in ch else np.stack([ch[c].pixels for c in 'RGB'], -1)
    return np.asarray(a, dtype=np.float32).astype(np.float64)


def mu(x):
    return np.log(1 + 5000 * x) / np.log(5001)


def field_metrics(g, p):
    kw = dict(channel_axis=-1, gaussian_weights=True, sigma=1.5, use_sample_covariance=False,
              data_range=255)
    c = lambda x: np.clip(x * 255, 0, 255)
    return dict(
        psnr_l=peak_signal_noise_ratio(g, p, data_range=1.0),
        psnr_t=peak_signal_noise_ratio(mu(g), mu(p), data_range=1.0),
        ssim_l=structural_similarity(c(g), c(p), **kw),
        ssim_t=structural_similarity(c(mu(g)), c(mu(p)), **kw),
    )


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    d = sys.argv[1] if len(sys.argv) > 1 else os.path.join(here, '../../shared/data/oracles')
    print('PU21 encoder (banding_glare):')
    for y in [0.001, 0.005, 0.1, 1.0, 10.0, 100.0, 1000.0, 4000.0, 10000.0, 20000.0]:
        print(f'  encode({y}) = {pu21_encode(np.float64(y))!r}')
    cases = json.load(open(os.path.join(d, 'oracles.json')))['metrics']['cases']
    for name, c in cases.items():
        g = read_exr(os.path.join(d, c['gt']))
        p = read_exr(os.path.join(d, c['pred']))
        m = field_metrics(g, p)
        diff = max(abs(m[k] - c[k]) for k in m)
        pp, ps = pu21_metrics(g, p)
        pp1, ps1 = pu21_metrics(g, p, reference_max=False)
        print(f'{name}: max |skimage - oracle| = {diff:.3g}; '
              f'pu21 ref-max: psnr={pp!r} ssim={ps!r}; pu21 unit: psnr={pp1!r} ssim={ps1!r}')


if __name__ == '__main__':
    main()
