#!/usr/bin/env python3
"""Reference values for the DNG tag reader and the DNG colour of src/sensor/dng (never a
runtime dependency).

Writes tests/data/dng_tags_reference.json with:
- `files`: for the three real DNGs under ../shared/data/real_raw (the Canon EOS 6D and iPhone 12
  Pro tag-only files in dng_tags/, the Canon 550D chart capture colorchart.dng), the tags as
  tifffile reads them (an independent TIFF/DNG reader): Make, Model, UniqueCameraModel, the
  EXIF ISO, the raw IFD's PhotometricInterpretation and BitsPerSample, ColorMatrix1/2,
  CalibrationIlluminant1/2, CameraCalibration1/2 and their signatures, AnalogBalance,
  AsShotNeutral, BlackLevel (+ repeat dims), WhiteLevel, NoiseProfile. Rationals are kept as
  [numerator, denominator] and doubles as their IEEE-754 bits, so a test can compare exactly.
- per file, `expected`: the DNG specification's camera-from-XYZ matrix for the white that
  AsShotNeutral represents, computed here in numpy, independently of the Rust code:
  CM_i = AnalogBalance · CameraCalibration_i · ColorMatrix_i (CameraCalibration only where
  CameraCalibrationSignature equals ProfileCalibrationSignature, as the specification says);
  starting from D50, repeat: weight g on CM_1 from the inverse correlated colour temperature
  (g = (1/T − 1/T2) / (1/T1 − 1/T2), clamped to [0, 1]), CM = g·CM_1 + (1 − g)·CM_2,
  xy of CM⁻¹ · neutral, its CCT; until xy moves less than 1e-13. The CCT comes from
  colour-science's `uv_to_CCT_Robertson1968` (Wyszecki & Stiles' isotemperature lines with
  Lindbloom's correction of the 325-mired u). Then the profile's colour T =
  rownorm(CM · M_sRGB), M_sRGB colour-science's sRGB RGB→XYZ matrix, each row scaled to sum 1;
  the profile's levels (mean black over the repeat pattern, the lowest white, bits to hold it)
  and noise a_c = S_c·r_c, b_c = O_c·r_c² with r_c = (W_c − B_c)/(W − B) (planes mapped to
  R, G, B by CFAPlaneColor; LinearRaw planes are R, G, B).
- `synthetic`: the same expected values for the tags of the synthetic DNG that
  tests/dng_tags.rs builds (the tag values are repeated below; the test checks they match).
- `cct`: colour-science's Robertson CCT of a few chromaticities.

Illuminant temperatures: CIE standard illuminants at their correlated colour temperatures
(A 2856 K, B 4874 K, C 6774 K, D50 5003 K, D55 5503 K, D65 6504 K, D75 7504 K); the other EXIF
light sources at the DNG SDK's values.

    python3 -m venv /tmp/colourenv && /tmp/colourenv/bin/pip install colour-science tifffile
    /tmp/colourenv/bin/python tools/dng_tags_reference.py
"""
import json
import os
import struct
import warnings

import numpy as np
import tifffile

warnings.filterwarnings("ignore")
import colour  # noqa: E402

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
SHARED = os.path.join(ROOT, "..", "shared", "data")
OUT = os.path.join(ROOT, "tests", "data", "dng_tags_reference.json")

FILES = {
    "canon_eos_6d": "real_raw/dng_tags/canon_eos_6d.dng",
    "iphone12pro": "real_raw/dng_tags/iphone12pro_IMG_1361.dng",
    "colorchart_550d": "real_raw/colorchart.dng",
}

TEMPERATURE = {
    1: 5500.0, 2: 4150.0, 3: 2856.0, 4: 5500.0, 9: 5500.0, 10: 6500.0, 11: 7500.0,
    12: 6400.0, 13: 5000.0, 14: 4150.0, 15: 3450.0, 16: 2925.0, 17: 2856.0, 18: 4874.0,
    19: 6774.0, 20: 5503.0, 21: 6504.0, 22: 7504.0, 23: 5003.0, 24: 3200.0,
}

M_SRGB = np.array(colour.RGB_COLOURSPACES["sRGB"].matrix_RGB_to_XYZ, dtype=float)
D50_XY = np.array([0.3457, 0.3585])


def cct(xy):
    uv = colour.xy_to_UCS_uv(np.asarray(xy, dtype=float))
    return float(colour.temperature.uv_to_CCT_Robertson1968(uv)[0])


def xy_of(xyz):
    return xyz[:2] / xyz.sum()


def spec_colour(cm1, cm2, t1, t2, ab, cc1, cc2, neutral):
    """The specification's interpolation; returns (cct, xy, weight on CM_1, CM)."""
    ab = np.diag(ab)
    m1 = ab @ cc1 @ cm1
    if cm2 is None:
        xy = xy_of(np.linalg.solve(m1, neutral))
        return cct(xy), xy, 1.0, m1
    m2 = ab @ cc2 @ cm2
    if t1 > t2:
        m1, m2, t1, t2 = m2, m1, t2, t1

    def weight(t):
        return float(np.clip((1.0 / t - 1.0 / t2) / (1.0 / t1 - 1.0 / t2), 0.0, 1.0))

    xy = D50_XY
    for _ in range(100):
        g = weight(cct(xy))
        cm = g * m1 + (1.0 - g) * m2
        nxt = xy_of(np.linalg.solve(cm, neutral))
        done = np.abs(nxt - xy).sum() < 1e-13
        xy = nxt
        if done:
            break
    t = cct(xy)
    g = weight(t)
    return t, xy, g, g * m1 + (1.0 - g) * m2


def rownorm(m):
    return m / m.sum(axis=1, keepdims=True)


def ratio_pairs(v):
    v = list(v)
    return [[int(v[i]), int(v[i + 1])] for i in range(0, len(v), 2)]


def as_floats(v):
    v = np.atleast_1d(v)
    return [float(x) for x in v]


def ratios(v):
    return np.array([n / d for n, d in ratio_pairs(v)])


def bits(x):
    return struct.unpack("<Q", struct.pack("<d", x))[0]


def raw_page(tf):
    """The IFD of the main raw image: NewSubfileType 0, CFA or LinearRaw."""
    pages = [tf.pages[0]] + list(tf.pages[0].pages or [])
    for p in pages:
        tags = p.tags
        if int(tags.valueof(254, 0)) == 0 and int(tags.valueof(262)) in (32803, 34892):
            return p
    raise SystemExit("no raw IFD")


def expected(t):
    """Expected colour, levels and noise from a dict of tag values (floats)."""
    out = {}
    cm1 = np.array(t["color_matrix1"]).reshape(3, 3)
    cm2 = None if t.get("color_matrix2") is None else np.array(t["color_matrix2"]).reshape(3, 3)
    use_cc = t.get("camera_calibration_signature") == t.get("profile_calibration_signature")
    cc = [
        np.array(t[k]).reshape(3, 3) if use_cc and t.get(k) is not None else np.eye(3)
        for k in ("camera_calibration1", "camera_calibration2")
    ]
    ab = np.array(t["analog_balance"]) if t.get("analog_balance") is not None else np.ones(3)
    temps = [TEMPERATURE.get(t.get(k)) for k in ("calibration_illuminant1", "calibration_illuminant2")]
    T, xy, g, cm = spec_colour(cm1, cm2, temps[0], temps[1], ab, cc[0], cc[1],
                               np.array(t["as_shot_neutral"]))
    out["cct"] = T
    out["xy"] = [float(v) for v in xy]
    out["weight_lower_temperature"] = g
    out["camera_from_xyz"] = cm.tolist()
    out["t"] = rownorm(cm @ M_SRGB).tolist()
    # Levels per channel.
    planes = t["plane_colours"]  # colour of plane p
    rr, rc = t["black_level_repeat"]
    black = np.array(t["black_level"], dtype=float)
    if t["photometric"] == 32803:
        cr, ccol = t["cfa_repeat"]
        pattern = t["cfa_pattern"]
        rows, cols = np.lcm(cr, rr), np.lcm(ccol, rc)
        per = {0: [], 1: [], 2: []}
        allb = []
        for i in range(rows):
            for j in range(cols):
                b = black[(i % rr) * rc + j % rc]
                per[planes[pattern[(i % cr) * ccol + j % ccol]]].append(b)
                allb.append(b)
        bc = np.array([np.mean(per[c]) for c in range(3)])
        bmean = np.mean(allb)
        white = np.array(t["white_level"] * 3 if len(t["white_level"]) == 1 else t["white_level"])
        bps = t["bits_per_sample"]
    else:
        n = 3
        bc = np.array([black[s::n].mean() for s in range(n)])
        bmean = black.mean()
        white = np.array(t["white_level"] if len(t["white_level"]) == 3 else t["white_level"] * 3,
                         dtype=float)
        bps = t["bits_per_sample"]
    delta = t.get("black_delta_mean", 0.0)
    bc = bc + delta
    bmean = bmean + delta
    W = float(white.min())
    nbits = max(bps, int(np.ceil(np.log2(W + 1.0))))
    out["levels"] = {"black_level": float(bmean), "white_level": W, "bit_depth": nbits}
    if t.get("noise_profile") is not None:
        npf = np.array(t["noise_profile"], dtype=float)
        if len(npf) == 2:
            S = np.full(3, npf[0])
            O = np.full(3, npf[1])
        else:
            S = np.zeros(3)
            O = np.zeros(3)
            for p in range(3):
                S[planes[p]] = npf[2 * p]
                O[planes[p]] = npf[2 * p + 1]
        r = (white - bc) / (W - bmean)
        out["noise"] = {"a": (S * r).tolist(), "b": (O * r * r).tolist()}
    return out


def read_file(rel):
    path = os.path.join(SHARED, rel)
    with tifffile.TiffFile(path) as tf:
        p0 = tf.pages[0]
        raw = raw_page(tf)
        g0 = p0.tags
        gr = raw.tags

        def tag(code, pref_raw=False):
            order = (gr, g0) if pref_raw else (g0, gr)
            for g in order:
                if code in g:
                    return g[code].value
            return None

        exif = g0[34665].value if 34665 in g0 else {}
        rec = {"file": rel}
        for code, key in ((271, "make"), (272, "model"), (50708, "unique_camera_model")):
            v = tag(code)
            rec[key] = v.strip("\0 ") if isinstance(v, str) else v
        rec["iso"] = int(exif.get("ISOSpeedRatings", 0)) or None
        rec["photometric"] = int(raw.tags[262].value)
        rec["bits_per_sample"] = int(np.atleast_1d(raw.tags[258].value)[0])
        for code, key in ((50721, "color_matrix1"), (50722, "color_matrix2"),
                          (50723, "camera_calibration1"), (50724, "camera_calibration2"),
                          (50727, "analog_balance"), (50728, "as_shot_neutral")):
            v = tag(code)
            rec[key] = None if v is None else ratio_pairs(v)
        for code, key in ((50778, "calibration_illuminant1"), (50779, "calibration_illuminant2")):
            v = tag(code)
            rec[key] = None if v is None else int(v)
        for code, key in ((50931, "camera_calibration_signature"),
                          (50932, "profile_calibration_signature")):
            v = tag(code)
            rec[key] = v.strip("\0") if isinstance(v, str) else v
        bl = tag(50714, pref_raw=True)
        bl_type = (gr[50714] if 50714 in gr else g0[50714]).dtype if bl is not None else None
        if bl is None:
            rec["black_level"] = [[0, 1]]
        elif int(bl_type) in (5, 10):
            rec["black_level"] = ratio_pairs(bl)
        else:
            rec["black_level"] = [[int(v), 1] for v in np.atleast_1d(bl)]
        rep = tag(50713, pref_raw=True)
        rec["black_level_repeat"] = [1, 1] if rep is None else [int(v) for v in rep]
        wl = tag(50717, pref_raw=True)
        rec["white_level"] = [int(v) for v in np.atleast_1d(wl)]
        npf = tag(51041, pref_raw=True)
        rec["noise_profile"] = None if npf is None else as_floats(npf)
        rec["noise_profile_bits"] = None if npf is None else [bits(v) for v in as_floats(npf)]
        if rec["photometric"] == 32803:
            rec["cfa_repeat"] = [int(v) for v in raw.tags[33421].value]
            rec["cfa_pattern"] = [int(v) for v in raw.tags[33422].value]
        plane = tag(50710, pref_raw=True)
        rec["plane_colours"] = [0, 1, 2] if plane is None else [int(v) for v in plane]
    return rec


def to_values(rec):
    """Tag values as floats for `expected`."""
    t = dict(rec)
    for k in ("color_matrix1", "color_matrix2", "camera_calibration1", "camera_calibration2",
              "analog_balance", "as_shot_neutral", "black_level"):
        if t.get(k) is not None:
            t[k] = [n / d for n, d in t[k]]
    return t


# The synthetic DNG of tests/dng_tags.rs (matrices as SRATIONAL over 10000, neutral as RATIONAL
# over 1000000): an RGGB CFA with per-position black levels and a BlackLevelDeltaH.
SYNTHETIC = {
    "photometric": 32803,
    "bits_per_sample": 12,
    "color_matrix1": [v / 10000 for v in (7546, -1435, -929, -3846, 11488, 2692, -332, 1209, 6370)],
    "color_matrix2": [v / 10000 for v in (7034, -804, -1014, -4420, 12564, 2058, -851, 1994, 5758)],
    "calibration_illuminant1": 17,
    "calibration_illuminant2": 21,
    "camera_calibration1": [v / 10000 for v in (9883, 0, 0, 0, 10000, 0, 0, 0, 10120)],
    "camera_calibration2": [v / 10000 for v in (9883, 0, 0, 0, 10000, 0, 0, 0, 10120)],
    "camera_calibration_signature": "com.example",
    "profile_calibration_signature": "com.example",
    "analog_balance": [v / 1000000 for v in (1100000, 1000000, 950000)],
    "as_shot_neutral": [v / 1000000 for v in (650000, 1000000, 450000)],
    "black_level": [64.0, 60.0, 68.0, 72.0],
    "black_level_repeat": [2, 2],
    "black_delta_mean": 2.0,
    "white_level": [4000],
    "cfa_repeat": [2, 2],
    "cfa_pattern": [0, 1, 1, 2],
    "plane_colours": [0, 1, 2],
    "noise_profile": [2.0e-5, 4.0e-8, 1.5e-5, 3.0e-8, 2.5e-5, 5.0e-8],
}


def main():
    files = {}
    for name, rel in FILES.items():
        rec = read_file(rel)
        rec["expected"] = expected(to_values(rec))
        files[name] = rec
    synthetic = {"tags": SYNTHETIC, "expected": expected(SYNTHETIC)}
    xys = [[0.3127, 0.3290], [0.3457, 0.3585], [0.44758, 0.40745], [0.2500, 0.2500],
           [0.3800, 0.3700], [0.5500, 0.4000], [0.3000, 0.3300], [0.4300, 0.4000],
           [0.2000, 0.2000], [0.6200, 0.3600]]
    out = {
        "generator": "tools/dng_tags_reference.py (tifffile %s, colour-science %s, numpy %s)"
        % (tifffile.__version__, colour.__version__, np.__version__),
        "files": files,
        "synthetic": synthetic,
        "cct": [{"xy": xy, "cct": cct(xy)} for xy in xys],
    }
    with open(OUT, "w") as f:
        json.dump(out, f, indent=1)
        f.write("\n")
    for name, rec in files.items():
        e = rec["expected"]
        print(name, rec.get("unique_camera_model"), "ISO", rec["iso"], "CCT %.2f" % e["cct"],
              "g %.6f" % e["weight_lower_temperature"])
        print("  CM", np.array(e["camera_from_xyz"]).round(6).tolist())
        print("  T ", np.array(e["t"]).round(6).tolist())
        print("  levels", e["levels"], "noise", e.get("noise"))
    e = synthetic["expected"]
    print("synthetic CCT %.3f g %.6f" % (e["cct"], e["weight_lower_temperature"]), e["levels"],
          e["noise"])


if __name__ == "__main__":
    main()
