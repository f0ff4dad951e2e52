#!/usr/bin/env python3
"""Variants of a real test set that each remove one way its frames differ from what the test
set's recorded curve predicts, so that `hdrsynth eval` shows which difference a network reacts
to.

For a test set built from real brackets (Kalantari layout, one set: SET/frame_{1,2,3}.tif,
SET/exposure.txt, SET/HDRImg.hdr; TESTSET/encoding.toml with a `lut` response, as `hdrsynth
loop` and `hdrsynth testset --brackets --profile` write it), writes under OUT one copy of the
test set per variant, the ground truth and encoding unchanged:

- `orig`: the frames as they are (a copy, to score beside the others);
- `floor_ref`: the reference frame's codes at or under FLOOR (default 8/255) replaced by the
  code the recorded curve gives the ground truth at the reference's exposure (the other frames
  as they are): what the reference would hold if its darkest codes carried the radiance;
- `synth`: every frame rendered from the ground truth through the recorded curve and rounded to
  8 bits: frames that agree exactly with the curve, without noise;
- `synth_plus_resid`: `synth` plus each real frame's high-frequency residual (the frame minus
  its 3×3 box mean): the real frames' noise and fine structure on frames that otherwise agree;
- `toe` (with --calibration FOLDER [--region left|right]): the frames as they are, the
  encoding's darkest codes (under code 26) re-estimated from the calibration frames: per code,
  the median over every pixel and frame showing that code of the radiance the frames at codes
  26–230 give it (triangle-weighted, through the recorded curve), made increasing. Only the
  encoding changes: the copy, merges and networks read the frames through it.

Frame k's linear value is HDR · 2^s_k (the ground truth in the unit of the stop-0 frame,
exposure.txt's s_k), as the test set's layout defines it.

Run: tools/frame_probes.py TESTSET OUT [--floor CODE] [--calibration FOLDER [--region R]]
Then: hdrsynth eval --checkpoint C --testset OUT/<variant> --out E (and --baseline copy|triangle).
Needs numpy, opencv-python-headless, pillow (for --calibration).
"""

import argparse
import re
import shutil
import tomllib
from pathlib import Path

import cv2
import numpy as np


def read_tif(path):
    im = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if im is None:
        raise SystemExit(f"{path}: not a readable image")
    return im[..., ::-1].astype(np.float64) / 65535.0


def write_tif(path, img):
    cv2.imwrite(str(path), (np.clip(img, 0, 1) * 65535).round().astype(np.uint16)[..., ::-1])


def copy_set(src, dst, frames=None, lut=None):
    shutil.rmtree(dst, ignore_errors=True)
    shutil.copytree(src, dst)
    sets = [p for p in Path(dst).iterdir() if p.is_dir()]
    if frames is not None:
        for k, f in enumerate(frames, start=1):
            write_tif(sets[0] / f"frame_{k}.tif", f)
    if lut is not None:
        enc = Path(dst) / "encoding.toml"
        text = enc.read_text()
        body = ", ".join(repr(float(v)) for v in lut)
        enc.write_text(re.sub(r"lut = \[[^\]]*\]", f"lut = [{body}]", text, count=1))


def toe_lut(lut, xs, folder, region):
    """The encoding's darkest codes re-estimated from a calibration bracket (see the module doc)."""
    from PIL import Image

    files = sorted(p for p in Path(folder).iterdir() if p.suffix.lower() in (".jpg", ".jpeg"))
    if not files:
        raise SystemExit(f"{folder}: no JPEG frames")
    frames, times = [], []
    for f in files:
        t = Image.open(f).getexif().get_ifd(0x8769).get(33434)  # Exif ExposureTime
        if not t:
            raise SystemExit(f"{f}: no EXIF ExposureTime")
        times.append(float(t))
        im = cv2.imread(str(f))[..., ::-1]
        w = im.shape[1] // 2
        frames.append(im[:, :w] if region == "left" else im[:, w:] if region == "right" else im)
    inv = np.interp(np.arange(256) / 255, lut, xs)  # code -> linear
    z = np.stack([np.concatenate([f[..., c] for c in range(3)], axis=1).astype(int) for f in frames])
    t = np.array(times)[:, None, None]
    lo, hi = 26, 230
    w = np.where((z >= lo) & (z <= hi), np.minimum(z + 1, 256 - z), 0).astype(float)
    e = (w * inv[z] / t).sum(0) / np.maximum(w.sum(0), 1e-12)
    seen = w.sum(0) > 0
    new = inv.copy()
    for code in range(lo):
        vals = np.concatenate([(e * times[j])[(z[j] == code) & seen] for j in range(len(frames))])
        if len(vals) >= 20:
            new[code] = np.median(vals)
    for code in range(lo - 1, -1, -1):
        new[code] = min(new[code], new[code + 1] - 1e-7)
    new[0] = max(new[0], 0.0)
    print("toe (code: recorded → re-estimated linear):",
          ", ".join(f"{c}: {inv[c]:.5f} → {new[c]:.5f}" for c in range(0, lo, 3)))
    return np.interp(xs, new, np.arange(256) / 255)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("testset")
    ap.add_argument("out")
    ap.add_argument("--floor", type=float, default=8.0, help="highest floor code (of 255)")
    ap.add_argument("--calibration", help="bracket folder whose frames re-estimate the toe")
    ap.add_argument("--region", default="all", choices=["left", "right", "all"])
    a = ap.parse_args()
    src = Path(a.testset)
    enc = tomllib.loads((src / "encoding.toml").read_text())
    if enc["response"].get("kind") != "lut":
        raise SystemExit(f"{src / 'encoding.toml'}: the probes need a `lut` response")
    lut = np.array(enc["response"]["lut"])
    xs = np.linspace(0, 1, len(lut))
    sets = [p for p in src.iterdir() if p.is_dir()]
    if len(sets) != 1:
        raise SystemExit(f"{src}: the probes take a test set of one set ({len(sets)} found)")
    s = sets[0]
    stops = [float(v) for v in (s / "exposure.txt").read_text().split()]
    gt = cv2.imread(str(s / "HDRImg.hdr"), cv2.IMREAD_UNCHANGED)[..., ::-1].astype(np.float64)
    real = [read_tif(s / f"frame_{k}.tif") for k in (1, 2, 3)]
    synth = [np.round(np.interp(np.clip(gt * 2**e, 0, 1), xs, lut) * 255) / 255 for e in stops]
    out = Path(a.out)
    copy_set(src, out / "orig")
    floor = a.floor / 255 + 1e-9
    copy_set(src, out / "floor_ref",
             [real[0], np.where(real[1] <= floor, synth[1], real[1]), real[2]])
    copy_set(src, out / "synth", synth)
    copy_set(src, out / "synth_plus_resid",
             [y + (f - cv2.blur(f, (3, 3))) for f, y in zip(real, synth)])
    for f, y, k in zip(real, synth, (1, 2, 3)):
        print(f"frame_{k}: mean |real − curve of ground truth| {np.mean(np.abs(f - y)) * 255:.2f} "
              f"codes; reference codes ≤ floor: {np.mean(f.max(-1) <= floor) * 100:.1f} %")
    if a.calibration:
        copy_set(src, out / "toe", lut=toe_lut(lut, xs, a.calibration, a.region))


if __name__ == "__main__":
    main()
