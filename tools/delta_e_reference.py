#!/usr/bin/env python3
"""Reference values for the ΔE2000 metric of src/eval/metrics.rs (never a runtime dependency).

Writes tests/data/delta_e_reference.json with, all computed by colour-science:
- `sharma`: the 34 CIEDE2000 test pairs of Sharma, Wu & Dalal (2005), Table 1, with the
  published ΔE00 (4 decimals) and colour-science's `delta_E(..., method='CIE 2000')`;
- `display_pairs`: display RGB pairs read as sRGB-encoded (Rec. 709 primaries, D65), neutral
  greys, saturated primaries and secondaries, near-black, slightly above 1 and random values,
  each with both Lab values and ΔE00;
- `mu_law_images`: two small linear HDR image pairs, μ-law tonemapped (μ = 5000) in numpy,
  then the same chain; the mean ΔE00 over pixels (what `Scores::delta_e2000` reports).

The chain: `sRGB_to_XYZ(rgb, chromatic_adaptation_transform=None)` (sRGB decoding, then the
IEC 61966-2-1 matrix), `XYZ_to_Lab(xyz, illuminant=xy of the matrix's white)` (the white of
the sRGB matrix, RGB (1, 1, 1) → XYZ (0.9505, 1, 1.089): display greys have a* = b* = 0),
`delta_E(lab1, lab2, method='CIE 2000')` (kL = kC = kH = 1). No clipping: values outside
[0, 1] go through the same formulas.

    python3 -m venv /tmp/colourenv && /tmp/colourenv/bin/pip install colour-science
    /tmp/colourenv/bin/python tools/delta_e_reference.py
"""
import json
import os
import warnings

import numpy as np

warnings.filterwarnings("ignore")
import colour  # noqa: E402

OUT = os.path.join(os.path.dirname(__file__), "..", "tests", "data", "delta_e_reference.json")

# Sharma, Wu & Dalal (2005), Table 1: L1 a1 b1 L2 a2 b2 ΔE00.
SHARMA = [
    (50.0000, 2.6772, -79.7751, 50.0000, 0.0000, -82.7485, 2.0425),
    (50.0000, 3.1571, -77.2803, 50.0000, 0.0000, -82.7485, 2.8615),
    (50.0000, 2.8361, -74.0200, 50.0000, 0.0000, -82.7485, 3.4412),
    (50.0000, -1.3802, -84.2814, 50.0000, 0.0000, -82.7485, 1.0000),
    (50.0000, -1.1848, -84.8006, 50.0000, 0.0000, -82.7485, 1.0000),
    (50.0000, -0.9009, -85.5211, 50.0000, 0.0000, -82.7485, 1.0000),
    (50.0000, 0.0000, 0.0000, 50.0000, -1.0000, 2.0000, 2.3669),
    (50.0000, -1.0000, 2.0000, 50.0000, 0.0000, 0.0000, 2.3669),
    (50.0000, 2.4900, -0.0010, 50.0000, -2.4900, 0.0009, 7.1792),
    (50.0000, 2.4900, -0.0010, 50.0000, -2.4900, 0.0010, 7.1792),
    (50.0000, 2.4900, -0.0010, 50.0000, -2.4900, 0.0011, 7.2195),
    (50.0000, 2.4900, -0.0010, 50.0000, -2.4900, 0.0012, 7.2195),
    (50.0000, -0.0010, 2.4900, 50.0000, 0.0009, -2.4900, 4.8045),
    (50.0000, -0.0010, 2.4900, 50.0000, 0.0010, -2.4900, 4.8045),
    (50.0000, -0.0010, 2.4900, 50.0000, 0.0011, -2.4900, 4.7461),
    (50.0000, 2.5000, 0.0000, 50.0000, 0.0000, -2.5000, 4.3065),
    (50.0000, 2.5000, 0.0000, 73.0000, 25.0000, -18.0000, 27.1492),
    (50.0000, 2.5000, 0.0000, 61.0000, -5.0000, 29.0000, 22.8977),
    (50.0000, 2.5000, 0.0000, 56.0000, -27.0000, -3.0000, 31.9030),
    (50.0000, 2.5000, 0.0000, 58.0000, 24.0000, 15.0000, 19.4535),
    (50.0000, 2.5000, 0.0000, 50.0000, 3.1736, 0.5854, 1.0000),
    (50.0000, 2.5000, 0.0000, 50.0000, 3.2972, 0.0000, 1.0000),
    (50.0000, 2.5000, 0.0000, 50.0000, 1.8634, 0.5757, 1.0000),
    (50.0000, 2.5000, 0.0000, 50.0000, 3.2592, 0.3350, 1.0000),
    (60.2574, -34.0099, 36.2677, 60.4626, -34.1751, 39.4387, 1.2644),
    (63.0109, -31.0961, -5.8663, 62.8187, -29.7946, -4.0864, 1.2630),
    (61.2901, 3.7196, -5.3901, 61.4292, 2.2480, -4.9620, 1.8731),
    (35.0831, -44.1164, 3.7933, 35.0232, -40.0716, 1.5901, 1.8645),
    (22.7233, 20.0904, -46.6940, 23.0331, 14.9730, -42.5619, 2.0373),
    (36.4612, 47.8580, 18.3852, 36.2715, 50.5065, 21.2231, 1.4146),
    (90.8027, -2.0831, 1.4410, 91.1528, -1.6435, 0.0447, 1.4441),
    (90.9257, -0.5406, -0.9208, 88.6381, -0.8985, -0.7239, 1.5381),
    (6.7747, -0.2908, -2.4247, 5.8714, -0.0985, -2.2286, 0.6377),
    (2.0776, 0.0795, -1.1350, 0.9033, -0.0636, -0.5514, 0.9082),
]

MATRIX = colour.models.RGB_COLOURSPACE_sRGB.matrix_RGB_to_XYZ
WHITE_XYZ = MATRIX @ np.ones(3)
WHITE_XY = colour.XYZ_to_xy(WHITE_XYZ)


def lab(rgb):
    xyz = colour.sRGB_to_XYZ(np.asarray(rgb, float), chromatic_adaptation_transform=None)
    return colour.XYZ_to_Lab(xyz, illuminant=WHITE_XY)


def de(lab1, lab2):
    return colour.delta_E(lab1, lab2, method="CIE 2000")


def mu_law(x):
    return np.log(1.0 + 5000.0 * x) / np.log(5001.0)


def main():
    assert np.allclose(MATRIX, [[0.4124, 0.3576, 0.1805], [0.2126, 0.7152, 0.0722],
                                [0.0193, 0.1192, 0.9505]], atol=0, rtol=0)
    sharma = []
    for row in SHARMA:
        l1, l2, pub = np.array(row[:3]), np.array(row[3:6]), row[6]
        sharma.append({"lab1": l1.tolist(), "lab2": l2.tolist(), "published": pub,
                       "colour_science": float(de(l1, l2))})

    rng = np.random.default_rng(20050101)
    rgb = [
        # Neutral greys, black and white.
        [0.0, 0.0, 0.0], [0.5, 0.5, 0.5], [0.18, 0.18, 0.18], [1.0, 1.0, 1.0], [0.02, 0.02, 0.02],
        # Saturated primaries, secondaries.
        [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 1.0, 0.0], [0.0, 1.0, 1.0],
        [1.0, 0.0, 1.0], [0.8, 0.1, 0.05],
        # Above the display's white (μ-law of values above 1), a small negative.
        [1.05, 1.02, 1.1], [-0.001, 0.01, 0.02],
    ]
    pairs_a = rgb + rng.uniform(0.0, 1.0, (12, 3)).tolist()
    # Second colour: greys against greys, primaries against nearby colours, random pairs.
    pairs_b = [
        [0.0, 0.0, 0.0], [0.52, 0.52, 0.52], [0.2, 0.2, 0.2], [0.98, 0.98, 0.98],
        [0.03, 0.03, 0.03], [0.9, 0.05, 0.05], [0.1, 0.95, 0.0], [0.0, 0.05, 0.9],
        [1.0, 0.9, 0.0], [0.0, 1.0, 0.8], [0.9, 0.0, 1.0], [0.7, 0.15, 0.1],
        [1.0, 1.0, 1.0], [0.0, 0.0, 0.0],
    ] + rng.uniform(0.0, 1.0, (12, 3)).tolist()
    display = []
    for a, b in zip(pairs_a, pairs_b):
        la, lb = lab(a), lab(b)
        display.append({"rgb1": a, "rgb2": b, "lab1": la.tolist(), "lab2": lb.tolist(),
                        "delta_e": float(de(la, lb))})

    images = []
    for (w, h), scale in [((4, 3), 1.0), ((5, 2), 4.0)]:
        gt = rng.uniform(0.0, scale, (h, w, 3)).astype(np.float32)
        pred = (gt * rng.uniform(0.7, 1.3, (h, w, 3))).astype(np.float32)
        # Values as the Rust code reads them: f32 images, μ-law in f64.
        tg, tp = mu_law(gt.astype(np.float64)), mu_law(pred.astype(np.float64))
        d = de(lab(tg.reshape(-1, 3)), lab(tp.reshape(-1, 3)))
        images.append({"width": w, "height": h, "gt": gt.reshape(-1).tolist(),
                       "pred": pred.reshape(-1).tolist(), "mean_delta_e": float(d.mean())})

    out = {
        "generator": "tools/delta_e_reference.py, colour-science " + colour.__version__
                     + ", numpy " + np.__version__,
        "white_xyz": WHITE_XYZ.tolist(),
        "sharma": sharma,
        "display_pairs": display,
        "mu_law_images": images,
    }
    os.makedirs(os.path.dirname(OUT), exist_ok=True)
    with open(OUT, "w") as f:
        json.dump(out, f, indent=1)
        f.write("\n")
    worst = max(abs(s["published"] - s["colour_science"]) for s in sharma)
    print(f"wrote {OUT}; colour-science vs Sharma's table: max |diff| {worst:.2e}")
    for k, s in enumerate(sharma):
        if abs(s["published"] - s["colour_science"]) > 5e-5:
            print(f"  pair {k + 1}: published {s['published']}, colour-science "
                  f"{s['colour_science']:.6f}")


if __name__ == "__main__":
    main()
