#!/usr/bin/env python3
"""Dev-time oracle for tests/brackets/response.rs and alignment.rs: OpenCV's
CalibrateDebevec response and AlignMTB shifts on small deterministic brackets. Writes
tests/data/brackets/:
  crf_{0..4}.png      an 8-bit bracket (times in crf_times.txt) of a synthetic scene through a
                      non-gamma response (1 - exp(-4x)) / (1 - exp(-4))
  crf_debevec.csv     OpenCV's response, 256 rows "r,g,b" (exp g(z), g(128) = 0), defaults
                      (samples 70, lambda 10, random false)
  crf_debevec_one_curve.csv
                      OpenCV's response of the same frames' three channels laid side by side as
                      one grey image three times as wide, samples 210, lambda 30 (hdrsynth's
                      one curve for the three channels: 3x OpenCV's samples and lambda),
                      256 rows "v"
  crf_robertson.csv   OpenCV's CalibrateRobertson response of the same frames, 256 rows
                      "r,g,b" (I(z), I(128) = 1; "nan" for codes never observed), defaults
                      (max_iter 30, threshold 0.01)
  mtb_{0,1,2}.png     160×128: one frame and two shifted, differently exposed copies
  mtb_shifts.txt      the applied shifts and OpenCV AlignMTB's calculateShift (x y per line)
Run: python3 -m venv v && v/bin/pip install opencv-python-headless numpy && v/bin/python tools/crf_oracle.py
"""
import os
import numpy as np
import cv2

OUT = os.path.join(os.path.dirname(__file__), "..", "tests", "data", "brackets")
os.makedirs(OUT, exist_ok=True)

W, H = 64, 48
y, x = np.mgrid[0:H, 0:W].astype(np.float64)
# Smooth but varied log-radiance over ~9 stops, colour varying.
u = 0.5 + 0.25 * np.sin(x / 5.0) * np.cos(y / 7.0) + 0.25 * (x / W - 0.5) + 0.2 * (y / H - 0.5)
lum = 2.0 ** (-9.0 + 9.0 * np.clip(u, 0, 1))
rad = np.stack([lum * 0.7, lum, lum * (0.5 + 0.5 * y / H)], axis=-1)


def response(v):
    v = np.clip(v, 0, 1)
    return (1 - np.exp(-4 * v)) / (1 - np.exp(-4))


times = [1 / 16, 1 / 4, 1.0, 4.0, 16.0]
frames = []
for i, t in enumerate(times):
    rgb = np.round(response(rad * t * 8.0) * 255).astype(np.uint8)
    frames.append(rgb)
    cv2.imwrite(os.path.join(OUT, f"crf_{i}.png"), cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
with open(os.path.join(OUT, "crf_times.txt"), "w") as f:
    f.write("\n".join(repr(t) for t in times) + "\n")

bgr = [cv2.cvtColor(fr, cv2.COLOR_RGB2BGR) for fr in frames]
crf = cv2.createCalibrateDebevec().process(bgr, np.array(times, dtype=np.float32))
crf = crf.reshape(256, 3)[:, ::-1]  # BGR -> RGB
with open(os.path.join(OUT, "crf_debevec.csv"), "w") as f:
    f.write("r,g,b\n")
    for r in crf:
        f.write(",".join(f"{v:.7g}" for v in r) + "\n")

tiled = [np.concatenate([fr[:, :, c] for c in range(3)], axis=1) for fr in frames]
one = cv2.createCalibrateDebevec(samples=210, lambda_=30.0).process(tiled, np.array(times, dtype=np.float32))
with open(os.path.join(OUT, "crf_debevec_one_curve.csv"), "w") as f:
    f.write("v\n")
    for r in one.reshape(256):
        f.write(f"{r:.7g}\n")

rob = cv2.createCalibrateRobertson().process(bgr, np.array(times, dtype=np.float32))
rob = rob.reshape(256, 3)[:, ::-1]
with open(os.path.join(OUT, "crf_robertson.csv"), "w") as f:
    f.write("r,g,b\n")
    for r in rob:
        f.write(",".join(f"{v:.7g}" for v in r) + "\n")

# MTB: a textured scene (blocks of random grey), three exposures, two shifted.
rng = np.random.default_rng(19)
MW, MH = 160, 128
blocks = rng.uniform(-4, 2, size=(MH // 8 + 2, MW // 8 + 2))
big = np.kron(blocks, np.ones((8, 8)))
big = cv2.GaussianBlur(big, (0, 0), 1.0)
shifts = [(0, 0), (3, -2), (-5, 4)]
with open(os.path.join(OUT, "mtb_shifts.txt"), "w") as f:
    imgs = []
    for i, ((dx, dy), t) in enumerate(zip(shifts, [0.25, 1.0, 4.0])):
        # Frame i shows the scene moved by (dx, dy): pixel (x, y) = scene(x - dx, y - dy).
        crop = big[8 - dy:8 - dy + MH, 8 - dx:8 - dx + MW]
        g = np.round(response(2.0 ** crop * t) * 255).astype(np.uint8)
        img = np.stack([g, g, g], axis=-1)
        imgs.append(img)
        cv2.imwrite(os.path.join(OUT, f"mtb_{i}.png"), img)
    align = cv2.createAlignMTB(4, 4, True)  # max_bits 4 (6 needs larger images), exclude 4
    ref = cv2.cvtColor(imgs[0], cv2.COLOR_BGR2GRAY)
    for i, (dx, dy) in enumerate(shifts):
        s = align.calculateShift(ref, cv2.cvtColor(imgs[i], cv2.COLOR_BGR2GRAY))
        f.write(f"{i} applied {dx} {dy} opencv {s[0]} {s[1]}\n")
print("wrote", OUT)
