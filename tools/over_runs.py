#!/usr/bin/env python3
"""Claims over training runs from a finished grid's per-seed table (docs/protocol.md,
"Statistics" and the `long` preset's deviation): the training run is the unit.

Reads EXP/table_seeds*.csv (`hdrsynth ablate` / `quickstart`: per row, seed and metric, the
mean over scenes) and prints, per test set, for PSNR-T:
  - each row's per-seed means and the run-to-run spread (sd over seeds);
  - Net_S − B for B in Net_R, the triangle merge and the copy, per seed (paired within seed:
    the same test noise), with the t 95 % interval over the seeds' differences and the number
    of seeds with the mean's sign;
  - the equivalence margin, the larger of 0.2 dB and the run-to-run spread of the reference
    row's mean, and whether the t 90 % interval of Net_S − Net_R lies inside ± it (TOST at
    5 %).

Run: tools/over_runs.py runs/quickstart_long/experiment [--reference net_r]
"""

import argparse
import csv
import math
import statistics
from pathlib import Path

# Student t quantiles by degrees of freedom (scipy.stats.t.ppf(q, df)).
T975 = {1: 12.7062, 2: 4.3027, 3: 3.1824, 4: 2.7764, 5: 2.5706, 6: 2.4469, 7: 2.3646,
        8: 2.3060, 9: 2.2622}
T95 = {1: 6.3138, 2: 2.9200, 3: 2.3534, 4: 2.1318, 5: 2.0150, 6: 1.9432, 7: 1.8946,
       8: 1.8595, 9: 1.8331}
MARGIN_FLOOR = 0.2


def per_seed(path: Path, metric: str) -> dict:
    """row -> seed -> mean over scenes."""
    out: dict = {}
    with open(path) as f:
        for r in csv.DictReader(f):
            if r["metric"] == metric and not r["column"] and r["mean"]:
                out.setdefault(r["row"], {})[int(r["seed"])] = float(r["mean"])
    return out


def interval(d: list, table: dict) -> tuple:
    m = statistics.fmean(d)
    half = table[len(d) - 1] * statistics.stdev(d) / math.sqrt(len(d))
    return m, m - half, m + half


def signed(v: float) -> str:
    return f"{'−' if v < 0 else '+'}{abs(v):.2f}"


def report(name: str, rows: dict, reference: str) -> None:
    print(f"\n## {name}")
    seeds = sorted(rows.get("net_s", {}))
    print(f"seeds {', '.join(map(str, seeds))}")
    for row, by in rows.items():
        vals = [by[s] for s in seeds if s in by]
        sd = statistics.stdev(vals) if len(vals) > 1 else float("nan")
        print(f"- {row}: {' / '.join(f'{v:.2f}' for v in vals)}; run-to-run sd {sd:.3f} dB")
    if len(seeds) < 2:
        return
    spread = statistics.stdev(rows[reference][s] for s in seeds)
    margin = max(MARGIN_FLOOR, spread)
    for other in (reference, "triangle", "copy"):
        if other not in rows:
            continue
        d = [rows["net_s"][s] - rows[other][s] for s in seeds]
        m, lo, hi = interval(d, T975)
        agree = sum(1 for v in d if (v > 0) == (m > 0))
        line = (f"- Net_S − {other}: {signed(m)} [{signed(lo)}, {signed(hi)}] over {len(d)} runs "
                f"(per seed {', '.join(signed(v) for v in d)}; sign in {agree}/{len(d)})")
        if other == reference:
            _, lo90, hi90 = interval(d, T95)
            inside = -margin < lo90 and hi90 < margin
            line += (f"; margin ±{margin:.2f} (spread {spread:.3f}): 90 % [{signed(lo90)}, "
                     f"{signed(hi90)}] {'inside: equivalent' if inside else 'not inside'}")
        print(line)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("exp", type=Path, help="the grid's folder (e.g. QS/experiment)")
    ap.add_argument("--reference", default="net_r")
    ap.add_argument("--metric", default="psnr_t")
    a = ap.parse_args()
    for path in sorted(a.exp.glob("table_seeds*.csv")):
        name = path.stem.removeprefix("table_seeds").lstrip("_") or "primary"
        report(name, per_seed(path, a.metric), a.reference)


if __name__ == "__main__":
    main()
