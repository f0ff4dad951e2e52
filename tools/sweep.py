#!/usr/bin/env python3
"""Quality against compute: the main job's recipe at other network widths and step counts.

For each point (width w, step factor k; suffix `m`: training scenes with moving subjects, the
scene engine's default motion, instead of the main job's static ones; suffix `h`: the same
scenes with half the samples still, `[data] static_fraction = 0.5`; suffix `q`: three
quarters of them still, `static_fraction = 0.75`; suffix `k`: the kernel head,
`[model] output = "kernel"`, instead of the merge head; suffix `r`: the merge head's prior
Robertson's weights, `[model] merge_prior = "robertson"`, instead of the triangle's; suffix
`p`: the loss averaged as PSNR-T averages images, `[loss] average = "psnr"`, instead of over
every pixel) of the
sweep, from a finished main job's folder QS (`hdrsynth quickstart --out QS`, whose training
data and test sets it reuses):
  - Net_O per seed: the main job's pretraining config with `model.base_width = w` (the merger
    widths scaled alike) and k times the steps (warm-up and checkpoints alike);
  - the main job's grid with Net_R, Net_S and the classical rows only, fine-tuned for k times
    the steps from that point's Net_O, on the main job's primary and dynamic test sets;
and writes OUT/sweep.csv: per point, test set and metric (PSNR-T, PSNR-T over the moving
pixels), each row's mean over seeds and scenes and the paired differences Net_S − Net_R,
Net_S − triangle, Net_S − Robertson and Net_S − copy (within seed and set; t 95 % interval
over scenes, each scene's difference the mean over its ISO sets and the seeds; each seed's mean),
and OUT/realism_vs_quality.png (`hdrsynth sweep-plot`): Net_S − Net_R against Net_S − triangle
per point and test set, and OUT/sweep_scenes.csv: per point, test set and scene, the triangle
merge's PSNR-T and Net_S − triangle. With `--pair A,B`, OUT/sweep_pairs.csv holds Net_S(A) − Net_S(B), paired
within seed and scene, per test set.

Every point is also scored on validation scenes of seeds used for nothing else (16 static,
16 with moving subjects: `val_static`, `val_dynamic`); a choice between points is made on them,
never on the main job's test sets.

Run: tools/sweep.py QS OUT --points 8x1,8x1m,8x1q,8x4h,8x1hk,16x1 --seeds 1,2,3 [--hdrsynth PATH]
Resumable: every stage is (`hdrsynth train --resume`, `hdrsynth ablate`).
Needs Python 3.11+ and tomli-w.
"""

import argparse
import csv
import math
import statistics
import subprocess
import sys
import tomllib
from pathlib import Path

import tomli_w


def load(path: Path) -> dict:
    with open(path, "rb") as f:
        return tomllib.load(f)


def save(path: Path, cfg: dict) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    tmp.write_bytes(tomli_w.dumps(cfg).encode())
    tmp.replace(path)


def scaled(cfg: dict, width: int, k: int, out: Path) -> dict:
    cfg = dict(cfg)
    run = dict(cfg["run"])
    run["out"] = str(out)
    run["steps"] = run["steps"] * k
    run["checkpoint_every"] = run["checkpoint_every"] * k
    cfg["run"] = run
    model = dict(cfg["model"])
    ratio = width / model["base_width"]
    model["base_width"] = width
    model["unet_merger_widths"] = [max(1, round(v * ratio)) for v in model["unet_merger_widths"]]
    cfg["model"] = model
    sched = dict(cfg["schedule"])
    sched["warmup_steps"] = sched["warmup_steps"] * k
    cfg["schedule"] = sched
    return cfg


# Student t 97.5 % quantiles by degrees of freedom (scipy.stats.t.ppf(0.975, df)).
T975 = {15: 2.1314, 23: 2.0687, 47: 2.0117}  # 15: 16 scenes, 23: 24 scenes


def per_image(path: Path, metric: str) -> dict:
    with open(path) as f:
        return {r["set"]: float(r[metric]) for r in csv.DictReader(f) if r.get(metric)}


def paired(a: dict, b: dict) -> tuple:
    """a, b: seed -> set -> value. Mean difference, t interval over scenes, per-seed means."""
    by_scene, per_seed = {}, []
    for k in a:
        d = {s: a[k][s] - b[k][s] for s in a[k] if s in b[k]}
        per_seed.append(statistics.fmean(d.values()))
        for s, v in d.items():
            by_scene.setdefault(s.rsplit("_iso", 1)[0], []).append(v)
    scenes = [statistics.fmean(v) for v in by_scene.values()]
    m = statistics.fmean(scenes)
    half = T975.get(len(scenes) - 1, 2.0) * statistics.stdev(scenes) / math.sqrt(len(scenes))
    return m, m - half, m + half, per_seed


def per_scene(point: str, testset: str, scores: dict) -> list:
    """Per scene of a test set: the triangle merge's PSNR-T and Net_S − triangle, each the mean
    over the scene's ISO sets and the seeds (where a point's static cost lies)."""
    acc = {}
    for seed, sets in scores["net_s"].items():
        for s, v in sets.items():
            tri = scores["triangle"][seed].get(s)
            if tri is not None:
                acc.setdefault(s.rsplit("_iso", 1)[0], []).append((tri, v - tri))
    return [{"point": point, "testset": testset, "scene": scene,
             "triangle": round(statistics.fmean(t for t, _ in v), 3),
             "net_s-triangle": round(statistics.fmean(d for _, d in v), 3)}
            for scene, v in sorted(acc.items())]


def run(cmd: list) -> None:
    print("+", " ".join(map(str, cmd)), flush=True)
    subprocess.run([str(c) for c in cmd], check=True)


# Validation scenes: the scene engine at seeds used for nothing else, 16 static and 16 with
# moving subjects, built as the main job builds its test scenes (192×144, at least 10 stops).
# Choices between sweep points are made on these; the main job's test sets are scored beside
# them and decide nothing.
VALIDATION = {"val_static": 707, "val_dynamic": 777}


def validation_scenes(hdrsynth: str, qs: Path, out: Path) -> dict:
    """Generate the validation scenes once; name -> the radiance a test set is built from."""
    base = load(qs / "configs/train_data.toml")
    found = {}
    for name, seed in VALIDATION.items():
        gen = dict(base, seed=seed, count=16, width=192, height=144)
        scene = dict(base["scene"], min_dynamic_range=10.0, motion_scale=1.0)
        if name == "val_static":
            scene["subjects"] = [0, 0]
        gen["scene"] = scene
        scenes = out / f"validation/{name}_scenes"
        if not (scenes / "dataset.toml").is_file():
            save(out / f"validation/{name}.toml", gen)
            run([hdrsynth, "generate", "--config", out / f"validation/{name}.toml",
                 "--out", scenes])
        if name == "val_static":
            # A static test set is built from a folder of radiance maps (the sets' hdr_gt.exr).
            maps = out / "validation/val_static_radiance"
            maps.mkdir(parents=True, exist_ok=True)
            for gt in sorted(scenes.glob("*/hdr_gt.exr")):
                to = maps / f"{gt.parent.name}.exr"
                if not to.is_file():
                    to.write_bytes(gt.read_bytes())
            found[name] = maps
        else:
            found[name] = scenes
    return found


def validation_specs(exp: dict, val: dict) -> list:
    """The validation sets as `also` test sets of the primary set's options and per-seed noise."""
    out = []
    for name, radiance in val.items():
        spec = dict(exp["testset"], name=name, radiance=str(radiance),
                    dir=str(radiance.parent / f"{name}_testset"),
                    label=f"validation scenes (seed {VALIDATION[name]}; chooses between points)")
        out.append(spec)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("qs", type=Path)
    ap.add_argument("out", type=Path)
    ap.add_argument("--points", default="8x1,8x4,16x1")
    ap.add_argument("--seeds", default="1,2")
    ap.add_argument("--hdrsynth", default="hdrsynth")
    ap.add_argument("--pair", action="append", default=[],
                    help="A,B: also Net_S of point A − Net_S of point B, paired within seed "
                         "and scene (OUT/sweep_pairs.csv); both points must be in --points")
    a = ap.parse_args()
    qs, out = a.qs.resolve(), a.out.resolve()
    seeds = [int(s) for s in a.seeds.split(",")]
    rows_kept = {"net_r", "net_s", "copy", "triangle", "robertson"}
    results = []
    net_s_of = {}  # (point, test set, metric) -> seed -> set -> Net_S's score
    scene_rows = []
    moving_data = qs / "data/train_moving"
    val = validation_scenes(a.hdrsynth, qs, out)
    for point in a.points.split(","):
        flags = point.split("x", 1)[1].lstrip("0123456789")
        still = 0.75 if "q" in flags else 0.5 if "h" in flags else 0.0
        mix = still > 0.0
        moving = mix or "m" in flags
        kernel = "k" in flags
        robertson = "r" in flags
        psnr_loss = "p" in flags
        width, k = (int(v) for v in point.rstrip("mhqkrp").split("x"))
        share = {0.5: "_half_still", 0.75: "_three_quarters_still"}.get(still, "")
        here = out / (f"w{width}_k{k}{share if mix else '_moving' if moving else ''}"
                      f"{'_kernel' if kernel else ''}{'_robertson' if robertson else ''}"
                      f"{'_psnr_loss' if psnr_loss else ''}")
        if moving and not (moving_data / "dataset.toml").is_file():
            gen = load(qs / "configs/train_data.toml")
            gen["scene"]["motion_scale"] = 1.0
            save(out / "train_moving.toml", gen)
            run([a.hdrsynth, "generate", "--config", out / "train_moving.toml",
                 "--out", moving_data])
        data = str(moving_data if moving else qs / "data/train")
        for s in seeds:
            pre = scaled(load(qs / f"configs/pretrain_seed{s}.toml"), width, k,
                         here / f"pretrain/seed{s}")
            pre["data"]["dataset"] = data
            if mix:
                pre["data"]["static_fraction"] = still
            if kernel:
                pre["model"]["output"] = "kernel"
            if robertson:
                pre["model"]["merge_prior"] = "robertson"
            if psnr_loss:
                pre.setdefault("loss", {})["average"] = "psnr"
            path = here / f"configs/pretrain_seed{s}.toml"
            save(path, pre)
            resume = ["--resume"] if (here / f"pretrain/seed{s}/checkpoints").is_dir() else []
            run([a.hdrsynth, "train", "--config", path, *resume])
        base = scaled(load(qs / "configs/finetune.toml"), width, k, here / "unused")
        base["data"]["dataset"] = data
        if mix:
            base["data"]["static_fraction"] = still
        if kernel:
            base["model"]["output"] = "kernel"
        if robertson:
            base["model"]["merge_prior"] = "robertson"
        if psnr_loss:
            base.setdefault("loss", {})["average"] = "psnr"
        save(here / "configs/finetune.toml", base)
        exp = load(qs / "configs/experiment.toml")
        exp["title"] = f"Sweep point: width {width}, {k}x the main job's steps"
        exp["out"] = str(here / "experiment")
        exp["base"] = str(here / "configs/finetune.toml")
        exp["seeds"] = seeds
        exp["pretrained_per_seed"] = str(here / "pretrain/seed{seed}")
        exp["rows"] = [r for r in exp["rows"] if r["name"] in rows_kept]
        exp["also"] = [t for t in exp.get("also", []) if t.get("name") == "dynamic"]
        exp["also"] += validation_specs(exp, val)
        save(here / "configs/experiment.toml", exp)
        run([a.hdrsynth, "ablate", "--config", here / "configs/experiment.toml"])
        cells = here / "experiment/cells"
        sets = [("primary", "eval"), ("dynamic", "eval_dynamic")] + [
            (v, f"eval_{v}") for v in VALIDATION
        ]
        for name, folder in sets:
            for metric in ("psnr_t", "psnr_t_moving"):
                scores = {
                    row: {s: per_image(cells / row / f"seed{s}" / folder / "per_image.csv",
                                       metric) for s in seeds}
                    for row in sorted(rows_kept)
                }
                if not any(scores["net_s"].values()):
                    continue
                net_s_of[(point, name, metric)] = scores["net_s"]
                if metric == "psnr_t":
                    scene_rows += per_scene(point, name, scores)
                line = {"width": width, "steps_factor": k, "moving_training": moving,
                        "static_fraction": still,
                        "head": "kernel" if kernel else "merge",
                        "prior": "robertson" if robertson else "triangle",
                        "loss": "psnr" if psnr_loss else "pixels",
                        "testset": name, "metric": metric}
                for row, v in scores.items():
                    line[row] = round(statistics.fmean(
                        statistics.fmean(x.values()) for x in v.values()), 3)
                for versus in ("net_r", "triangle", "robertson", "copy"):
                    m, lo, hi, ps = paired(scores["net_s"], scores[versus])
                    line[f"net_s-{versus}"] = round(m, 3)
                    line[f"net_s-{versus}_ci"] = f"[{lo:+.2f}, {hi:+.2f}]"
                    line[f"net_s-{versus}_per_seed"] = " ".join(f"{v:+.2f}" for v in ps)
                results.append(line)
                print(line, flush=True)
    out.mkdir(parents=True, exist_ok=True)
    with open(out / "sweep.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(results[0].keys()) if results else ["width"])
        w.writeheader()
        w.writerows(results)
    print(f"wrote {out / 'sweep.csv'}", file=sys.stderr)
    pairs = []
    for spec in a.pair:
        pa, pb = spec.split(",")
        for (point, name, metric), scores in net_s_of.items():
            other = net_s_of.get((pb, name, metric))
            if point != pa or other is None:
                continue
            m, lo, hi, ps = paired(scores, other)
            pairs.append({"a": pa, "b": pb, "testset": name, "metric": metric,
                          "net_s_a-net_s_b": round(m, 3), "ci": f"[{lo:+.2f}, {hi:+.2f}]",
                          "per_seed": " ".join(f"{v:+.2f}" for v in ps)})
            print(pairs[-1], flush=True)
    if scene_rows:
        with open(out / "sweep_scenes.csv", "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(scene_rows[0].keys()))
            w.writeheader()
            w.writerows(scene_rows)
    if pairs:
        with open(out / "sweep_pairs.csv", "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(pairs[0].keys()))
            w.writeheader()
            w.writerows(pairs)
    if results:
        run([a.hdrsynth, "sweep-plot", "--sweep", out / "sweep.csv",
             "--out", out / "realism_vs_quality.png"])


if __name__ == "__main__":
    main()
