#!/usr/bin/env python3
"""Rewrite an hdrsynth test set (hdrsynth testset) in Kalantari & Ramamoorthi's layout, as an
outside tool of the field would hold it: per set three 16-bit TIFFs (file-name order = exposure
order), exposure.txt and HDRImg.hdr (Radiance RGBE).

Dev-time tool for held-out checks (docs/experiments.md): `hdrsynth eval` must give the same
scores on the converted folder as on the original. Independent of hdrsynth's code: OpenCV and
OpenEXR's Python binding read and write every file.

  --stops shortest  exposure.txt "0 2 4", HDRImg.hdr in units of the SHORTEST frame's white
                    (HDR = LDR^gamma / 2^s with s as written, HDR-Transformer's read_expo_times)
  --stops reference exposure.txt "-2 0 2", HDRImg.hdr in units of the middle frame's white

usage: python tools/to_kalantari.py SRC DST [--stops shortest]
(needs opencv-python-headless, OpenEXR and numpy from PyPI; DST must not exist)
"""
import argparse
import os
import sys

import cv2  # noqa: E402
import numpy as np  # noqa: E402
import OpenEXR  # noqa: E402


def tomllite_evs(meta):
    for line in open(meta, encoding="utf-8"):
        if line.startswith("evs"):
            return [float(v) for v in line.split("=", 1)[1].strip(" []\n").split(",")]
    raise SystemExit(f"{meta}: no evs line")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("src")
    ap.add_argument("dst")
    ap.add_argument("--stops", choices=["shortest", "reference"], default="shortest")
    a = ap.parse_args()
    if os.path.exists(a.dst):
        sys.exit(f"{a.dst}: exists; choose a new folder")
    sets = sorted(d for d in os.listdir(a.src) if os.path.isfile(os.path.join(a.src, d, "meta.toml")))
    if not sets:
        sys.exit(f"{a.src}: no hdrsynth sets (folders with meta.toml)")
    tmp = a.dst + ".partial"
    os.makedirs(tmp)
    for name in sets:
        s = os.path.join(a.src, name)
        evs = tomllite_evs(os.path.join(s, "meta.toml"))
        if len(evs) != 3:
            sys.exit(f"{s}: Kalantari sets have three exposures, this one has {evs}")
        out = os.path.join(tmp, name)
        os.makedirs(out)
        for i, ev in enumerate(evs):
            png = os.path.join(s, "dynamic", f"ev{ev:+.0f}.png")
            img = cv2.imread(png, cv2.IMREAD_UNCHANGED)
            if img is None or img.dtype != np.uint8:
                sys.exit(f"{png}: expected an 8-bit PNG")
            # 8-bit code k → 16-bit 257·k: the same value k/255 on a 0..1 scale.
            cv2.imwrite(os.path.join(out, f"{name}_{i + 1}.tif"), img.astype(np.uint16) * 257)
        shift = evs[0] if a.stops == "shortest" else evs[1]
        stops = [ev - shift for ev in evs]
        with open(os.path.join(out, "exposure.txt"), "w") as f:
            f.write("".join(f"{v:g}\n" for v in stops))
        with OpenEXR.File(os.path.join(s, "hdr_gt.exr")) as f:
            ch = f.channels()
            rgb = ch["RGB"].pixels if "RGB" in ch else np.dstack([ch[c].pixels for c in "RGB"])
        gt = rgb[:, :, ::-1]  # OpenCV writes BGR
        # hdr_gt.exr is in units of the middle frame's white (s = 0 there); in the file's unit
        # the middle frame has stop s_mid, and HDR = LDR^gamma / 2^s_mid.
        gt = gt[:, :, :3].astype(np.float32) / (2.0 ** stops[1])
        cv2.imwrite(os.path.join(out, "HDRImg.hdr"), gt)
    os.rename(tmp, a.dst)
    print(f"{a.dst}: {len(sets)} Kalantari sets, exposure.txt as {a.stops}")


if __name__ == "__main__":
    main()
