#!/usr/bin/env python3
"""Dev-time generator of the MergeRobertson oracles in tests/data/oracle_crops/ (never a runtime
dependency).

Reads the committed three-frame brackets `<scene>_ev-2.png, _ev+0.png, _ev+2.png` (written by
tools/oracle_crops.py with a gamma-2.2 encoding), runs OpenCV's
`cv2.createMergeRobertson().process(frames_bgr, times, response)` on them with t = (0.25, 1, 4)
and the known gamma-2.2 response, and writes `<scene>_3exp_robertson.exr` (RGB float32) plus the
`robertson_merge` cases of oracles.json. Touches nothing else: the PNGs are only read, and the
other entries of oracles.json are kept as they are. tools/oracle_crops.py calls `add_cases`
after writing its own outputs, so a full regeneration keeps these cases.

The response table is R[z] = (z/255)^2.2 (MergeRobertson uses the table itself, not its log, so
R[0] = 0 is kept), 256x1x3 float32, the same in every channel. OpenCV weights each channel's
code with its RobertsonWeights (a Gaussian, exactly 0 at codes 0 and 255) and returns
sum t w R(z) / (sum t^2 w + DBL_EPSILON) per channel, in float32: a value clipped in every
frame merges to 0.

    python3 -m venv /tmp/cropsenv
    /tmp/cropsenv/bin/pip install opencv-python-headless numpy OpenEXR
    /tmp/cropsenv/bin/python tools/robertson_oracle.py [tests/data/oracle_crops]
"""
import os
import sys
from importlib.metadata import version

import cv2
import numpy as np

from debevec_oracle import GAMMA, HERE, add_merge_cases


def gamma_response():
    """256x1x3 float32: R[z] = (z/255)^2.2."""
    r = (np.arange(256, dtype=np.float64) / 255.0) ** GAMMA
    return np.ascontiguousarray(np.repeat(r[:, None, None], 3, axis=2), dtype=np.float32)


def add_cases(out):
    """Writes `<scene>_3exp_robertson.exr` for each scene and adds its case to out/oracles.json."""
    response = gamma_response()
    add_merge_cases(
        out, "robertson_merge", "robertson",
        lambda bgr, t: cv2.createMergeRobertson().process(bgr, times=t, response=response),
        "R[z] = (z/255)^2.2; float32 256x1x3")


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else os.path.join(HERE, "../tests/data/oracle_crops")
    add_cases(out)
    print(f"opencv-python-headless {version('opencv-python-headless')}, cv2 {cv2.__version__}")


if __name__ == "__main__":
    main()
