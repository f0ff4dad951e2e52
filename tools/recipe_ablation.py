#!/usr/bin/env python3
"""Dev-time analysis of the Network-2 recipe ablation (docs/experiments.md, "Recipe").

Reads per-image scores (hdrsynth eval's per_image.csv) of Net_S trained with the main job's
recipe and with one change undone at a time (tools/recipe_ablation.sh), and prints, per
variant, the mean PSNR-T on the primary test set, each seed's mean, and the paired difference
to the full recipe within seed and set: mean, per seed, and a paired t 95 % interval over
scenes (each scene's difference the mean over its ISO sets and the seeds). Standard library
only.

    python3 tools/recipe_ablation.py QUICKSTART_DIR ABLATION_DIR [BASELINE_QUICKSTART_DIR]
"""
import csv
import math
import os
import statistics
import sys

T975 = {23: 2.0687}  # Student t, 97.5 % quantile, 23 degrees of freedom (24 scenes)


def per_image(path, metric="psnr_t"):
    with open(path) as f:
        return {r["set"]: float(r[metric]) for r in csv.DictReader(f)}


def scene(set_name):
    return set_name.rsplit("_iso", 1)[0]


def main():
    qs, abl = sys.argv[1], sys.argv[2]
    base = sys.argv[3] if len(sys.argv) > 3 else None
    seeds = [1, 2, 3]
    full = {k: per_image(f"{qs}/experiment/cells/net_s/seed{k}/eval/per_image.csv") for k in seeds}
    rows = [("the main job's recipe (its Net_S)", full)]
    for name, kind in [
        ("image", "image head (Wu's) instead of the merge head"),
        ("gamma22", "inputs LDR^2.2 for every device (Wu's) instead of the training curve"),
        ("reference_unit", "the loss in the reference unit (option) instead of Wu's 0.25·H"),
        ("dynamic", "training scenes with moving subjects instead of static ones"),
        ("kernel", "the kernel head (option) instead of the merge head"),
    ]:
        paths = {k: f"{abl}/{name}/seed{k}/ev_primary/per_image.csv" for k in seeds}
        if all(os.path.isfile(p) for p in paths.values()):
            rows.append((kind, {k: per_image(p) for k, p in paths.items()}))
    if base:
        rows.append(("Wu's recipe as released (all three undone)",
                     {k: per_image(f"{base}/experiment/cells/net_s/seed{k}/eval/per_image.csv")
                      for k in seeds}))
    for cls in ["copy", "triangle", "debevec"]:
        paths = {k: f"{qs}/experiment/cells/{cls}/seed{k}/eval/per_image.csv" for k in seeds}
        if all(os.path.isfile(p) for p in paths.values()):
            rows.append((f"{cls} (no network)", {k: per_image(p) for k, p in paths.items()}))
    print("| Net_S trained with | PSNR-T | per seed | Δ to the main job's recipe [95 % t over scenes] | per seed |")
    print("|---|---|---|---|---|")
    for label, v in rows:
        mean = statistics.mean(statistics.mean(v[k].values()) for k in seeds)
        per_seed = ", ".join(f"{statistics.mean(v[k].values()):.2f}" for k in seeds)
        if v is full:
            print(f"| {label} | {mean:.2f} | {per_seed} | (reference) | |")
            continue
        by_scene = {}
        seed_d = []
        for k in seeds:
            d = {s: v[k][s] - full[k][s] for s in full[k]}
            seed_d.append(statistics.mean(d.values()))
            for s, x in d.items():
                by_scene.setdefault(scene(s), []).append(x)
        sd = [statistics.mean(x) for x in by_scene.values()]
        m = statistics.mean(sd)
        half = T975.get(len(sd) - 1, 2.0) * statistics.stdev(sd) / math.sqrt(len(sd))
        ps = ", ".join(f"{x:+.2f}" for x in seed_d)
        print(f"| {label} | {mean:.2f} | {per_seed} | {m:+.2f} [{m - half:+.2f}, {m + half:+.2f}] | {ps} |")


if __name__ == "__main__":
    main()
