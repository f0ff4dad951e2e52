#!/usr/bin/env python3
"""Writes tests/data/jpeg_quality/q<Q>.jpg: a 32×24 gradient saved by Pillow (libjpeg's
jpeg_set_quality, baseline Annex K tables) at each quality, and q<Q>_tables.txt with the
tables Pillow reports (natural order, one table per line, "id: v0 v1 …"). The test reads the
files' DQT back and estimates the quality (tests/jpeg.rs)."""
import pathlib
from PIL import Image

out = pathlib.Path(__file__).resolve().parent.parent / "tests/data/jpeg_quality"
out.mkdir(parents=True, exist_ok=True)
img = Image.new("RGB", (32, 24))
img.putdata([(8 * x, 10 * y, 4 * (x + y)) for y in range(24) for x in range(32)])
for q in (10, 50, 75, 90, 95, 100):
    path = out / f"q{q}.jpg"
    img.save(path, quality=q, subsampling=2)
    tables = Image.open(path).quantization
    lines = [f"{k}: " + " ".join(str(v) for v in tables[k]) for k in sorted(tables)]
    (out / f"q{q}_tables.txt").write_text("\n".join(lines) + "\n")
