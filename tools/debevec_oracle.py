#!/usr/bin/env python3
"""Dev-time generator of the MergeDebevec oracles in tests/data/oracle_crops/ (never a runtime
dependency).

Reads the committed three-frame brackets `<scene>_ev-2.png, _ev+0.png, _ev+2.png` (written by
tools/oracle_crops.py with a gamma-2.2 encoding), runs OpenCV's
`cv2.createMergeDebevec().process(frames_bgr, times, response)` on them with t = (0.25, 1, 4) and
the known gamma-2.2 response, and writes `<scene>_3exp_debevec.exr` (RGB float32) plus the
`debevec_merge` cases of oracles.json. Touches nothing else: the PNGs are only read, and the
other entries of oracles.json are kept as they are. tools/oracle_crops.py calls `add_cases`
after writing its own outputs, so a full regeneration keeps these cases.

The response table is R[z] = (z/255)^2.2 for z >= 1 and R[0] = (0.5/255)^2.2 (the value at
half a code: MergeDebevec takes log of the table, and the curve is 0 at code 0), 256x1x3
float32, the same in every channel. OpenCV 5.0 (and 4.x since opencv/opencv#27270) weights the
codes with its triangleWeights (z for 1..127, 255 - z for 128..254, 1e-6 at 0 and 255), averages
them over the channels, and returns exp(sum w (ln R(z) - ln t) / sum w) per channel, in float32.

    python3 -m venv /tmp/cropsenv
    /tmp/cropsenv/bin/pip install opencv-python-headless numpy OpenEXR
    /tmp/cropsenv/bin/python tools/debevec_oracle.py [tests/data/oracle_crops]
"""
import json
import os
import sys
from importlib.metadata import version

import cv2
import numpy as np
import OpenEXR

HERE = os.path.dirname(os.path.abspath(__file__))
SCENES = ("desk", "carrots")
EVS = [-2, 0, 2]
GAMMA = 2.2


def write_exr(path, rgb):
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    rgb = np.ascontiguousarray(rgb, dtype=np.float32)
    with OpenEXR.File(header, {"RGB": rgb}) as f:
        f.write(path)


def read_png_bgr(path):
    im = cv2.imread(path, cv2.IMREAD_UNCHANGED)
    assert im is not None and im.dtype == np.uint8 and im.shape[2] == 3, path
    return im


def gamma_response():
    """256x1x3 float32: R[z] = (z/255)^2.2, R[0] = (0.5/255)^2.2."""
    z = np.arange(256, dtype=np.float64) / 255.0
    z[0] = 0.5 / 255.0
    r = z ** GAMMA
    return np.ascontiguousarray(np.repeat(r[:, None, None], 3, axis=2), dtype=np.float32)


def add_merge_cases(out, kind, suffix, merge, response_note):
    """Runs `merge(frames_bgr, times)` on each scene's three-frame bracket, writes
    `<scene>_3exp_<suffix>.exr` and adds the case (kind `kind`) to out/oracles.json, replacing a
    case of the same name and keeping every other entry and its order."""
    path = os.path.join(out, "oracles.json")
    with open(path) as f:
        doc = json.load(f)
    times = [2.0 ** ev for ev in EVS]
    for name in SCENES:
        files = [f"{name}_ev{ev:+d}.png" for ev in EVS]
        bgr = [read_png_bgr(os.path.join(out, f)) for f in files]
        merged = merge(bgr, np.float32(times))
        assert merged.dtype == np.float32 and merged.shape == bgr[0].shape, merged.shape
        case = f"{name}_3exp_{suffix}"
        write_exr(os.path.join(out, f"{case}.exr"), merged[..., ::-1])
        doc["cases"][case] = dict(
            kind=kind, inputs=files, exposure_times=times, gamma=GAMMA,
            response=response_note, opencv=version("opencv-python-headless"),
            output=f"{case}.exr")
    with open(path, "w") as f:
        json.dump(doc, f, indent=1)
        f.write("\n")


def add_cases(out):
    """Writes `<scene>_3exp_debevec.exr` for each scene and adds its case to out/oracles.json."""
    response = gamma_response()
    add_merge_cases(
        out, "debevec_merge", "debevec",
        lambda bgr, t: cv2.createMergeDebevec().process(bgr, times=t, response=response),
        "R[z] = (z/255)^2.2 for z >= 1, R[0] = (0.5/255)^2.2; float32 256x1x3")


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else os.path.join(HERE, "../tests/data/oracle_crops")
    add_cases(out)
    print(f"opencv-python-headless {version('opencv-python-headless')}, cv2 {cv2.__version__}")


if __name__ == "__main__":
    main()
