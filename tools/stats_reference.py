#!/usr/bin/env python3
"""Dev-time reference values for the paired-difference tests of src/stats.rs (never a runtime
dependency). Writes tests/data/stats_reference.json, read by tests/stats.rs.

Generated with Python 3.11.7, numpy 2.4.6, scipy 1.17.1, statsmodels 0.15.0:
    python3 -m pip install --user numpy==2.4.6 scipy==1.17.1 statsmodels==0.15.0
    python3 tools/stats_reference.py            # from the repository root

What each value is:
- Student's t CDF and quantile: scipy.stats.t.cdf / scipy.stats.t.ppf on a grid of (x, df).
- Paired t: scipy.stats.ttest_1samp(d, 0) (statistic, pvalue, two-sided) and its
  confidence_interval(level); mean, sample sd (ddof=1) and se = sd/sqrt(n) from numpy.
- Wilcoxon signed rank: scipy.stats.wilcoxon(d, zero_method='wilcox', correction=False,
  alternative='two-sided', method=M) with M = 'exact' when the non-zero differences number at
  most 50 and their absolute values have no ties, else M = 'asymptotic' (scipy's current name
  for 'approx': normal approximation with the tie-corrected variance). W+ is the statistic of
  the same call with alternative='greater'. 'zstatistic' is scipy's (-|z| for two-sided).
- TOST: computed directly with scipy.stats.t (t_lower = (mean + margin)/se with p_lower =
  t.sf(t_lower, n-1); t_upper = (mean - margin)/se with p_upper = t.cdf(t_upper, n-1);
  p = max; (1 - 2 alpha) interval mean -/+ t.ppf(1 - alpha, n-1) se), and checked against
  statsmodels.stats.weightstats.ttost_paired(d, 0, -margin, margin) where that is finite.

The differences are written with Python's repr (shortest round-trip); random cases derive from
fixed numpy seeds and are rounded to 6 decimals.
"""
import json
import math
import os
import platform
import sys
import warnings

import numpy as np
import scipy
import statsmodels
from scipy import stats
from statsmodels.stats.weightstats import ttost_paired

OUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests", "data",
                   "stats_reference.json")


def rnd(seed, n, loc, scale):
    rng = np.random.default_rng(seed)
    return [round(float(v), 6) for v in rng.normal(loc, scale, n)]


# (name, differences, expect ties among non-zero |d|)
CASES = [
    ("n2", [0.3, 1.1], False),
    ("n3_mixed", [-0.4, 0.25, 1.5], False),
    ("n3_negative_with_zero", [0.0, -0.7, -1.9], False),
    ("n5_positive", [0.12, 0.31, -0.05, 0.44, 0.27], False),
    ("n5_all_equal", [0.5] * 5, True),
    ("n5_one_tie", [0.5, -0.5, 0.2, 0.9, 0.35], True),
    ("n10_zeros", [0.0, 0.8, -0.3, 1.2, 0.0, 0.45, 0.9, -0.1, 0.6, 0.35], False),
    ("n10_ties", [0.5, -0.5, 0.25, 0.75, 0.5, 1.0, -0.25, 0.5, 0.125, 0.75], True),
    ("n10_p_near_1", [-1.3, 1.2, -0.7, 0.8, -0.2, 0.15, 0.9, -0.95, 0.4, -0.31], False),
    ("n20_negative", rnd(1, 20, -0.3, 0.5), False),
    ("n20_tiny_p", [abs(v) + 0.5 for v in rnd(2, 20, 1.0, 0.3)], False),
    ("n24_small_positive", rnd(3, 24, 0.04, 0.15), False),
    ("n24_ties_zeros", [round(v, 1) for v in rnd(4, 24, 0.1, 0.4)], True),
    ("n51_one_zero", [0.0] + rnd(5, 50, 0.2, 1.0), False),
    ("n60_tiny_p", [abs(v) for v in rnd(6, 60, 2.0, 1.0)], False),
    ("n60_ties_mean_near_0", [round(v, 1) for v in rnd(7, 60, 0.0, 1.0)], True),
]

T_CDF_X = [-1e3, -40.0, -5.0, -2.1, -0.3, 0.0, 0.7, 1.96, 8.0, 1e3]
T_DFS = [0.5, 1.0, 1.5, 2.0, 3.0, 4.5, 9.0, 23.0, 59.0, 200.0, 1e4]
T_PPF_P = [1e-12, 1e-4, 0.025, 0.05, 0.3, 0.5, 0.8, 0.95, 0.975, 0.999999]


def t_distribution():
    cdf, ppf = [], []
    for df in T_DFS:
        for x in T_CDF_X:
            v = float(stats.t.cdf(x, df))
            # Subnormal and underflowed tails carry no relative precision to compare.
            if v > 1e-250:
                cdf.append({"x": x, "df": df, "cdf": v})
        for p in T_PPF_P:
            ppf.append({"p": p, "df": df, "quantile": float(stats.t.ppf(p, df))})
    return {"cdf": cdf, "quantile": ppf}


def paired_t(d, level):
    a = np.asarray(d, dtype=np.float64)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        res = stats.ttest_1samp(a, 0.0)
        ci = res.confidence_interval(level)
    sd = float(np.std(a, ddof=1))
    return {
        "level": level,
        "n": len(d),
        "mean": float(np.mean(a)),
        "sd": sd,
        "se": sd / math.sqrt(len(d)),
        "t": float(res.statistic),
        "p": float(res.pvalue),
        "ci_lower": float(ci.low),
        "ci_upper": float(ci.high),
    }


def wilcoxon(d, expect_ties):
    nz = [v for v in d if v != 0.0]
    ties = len(set(abs(v) for v in nz)) < len(nz)
    assert ties == expect_ties, "tie status of the case is not the intended one"
    method = "exact" if len(nz) <= 50 and not ties else "asymptotic"
    kw = dict(zero_method="wilcox", correction=False, method=method)
    two = stats.wilcoxon(d, alternative="two-sided", **kw)
    w_plus = float(stats.wilcoxon(d, alternative="greater", **kw).statistic)
    n = len(nz)
    out = {
        "method": "exact" if method == "exact" else "approx",
        "n": n,
        "statistic": float(two.statistic),
        "w_plus": w_plus,
        "w_minus": n * (n + 1) / 2 - w_plus,
        "p": float(two.pvalue),
    }
    if method == "asymptotic":
        out["zstatistic"] = float(two.zstatistic)
    return out


def tost(d, margin, alpha):
    a = np.asarray(d, dtype=np.float64)
    n = len(d)
    mean = np.float64(np.mean(a))
    se = np.float64(np.std(a, ddof=1) / math.sqrt(n))
    df = n - 1
    with np.errstate(divide="ignore", invalid="ignore"):
        t_lower = (mean + margin) / se
        t_upper = (mean - margin) / se
    p_lower = float(stats.t.sf(t_lower, df))
    p_upper = float(stats.t.cdf(t_upper, df))
    p = max(p_lower, p_upper)
    crit = float(stats.t.ppf(1.0 - alpha, df))
    lo, hi = float(mean - crit * se), float(mean + crit * se)
    with warnings.catch_warnings(), np.errstate(divide="ignore", invalid="ignore"):
        warnings.simplefilter("ignore", RuntimeWarning)
        sm_p, (sm_t1, sm_p1, _), (sm_t2, sm_p2, _) = ttost_paired(a, np.zeros(n), -margin, margin)
    if np.isfinite(se) and se > 0:
        for mine, theirs in [(p, sm_p), (p_lower, sm_p1), (p_upper, sm_p2),
                             (float(t_lower), sm_t1), (float(t_upper), sm_t2)]:
            assert math.isclose(mine, float(theirs), rel_tol=1e-12, abs_tol=1e-300), (mine, theirs)
    assert (p < alpha) == (-margin < lo and hi < margin), (d, margin, p, lo, hi)
    return {
        "margin": margin,
        "alpha": alpha,
        "t_lower": float(t_lower),
        "p_lower": p_lower,
        "t_upper": float(t_upper),
        "p_upper": p_upper,
        "p": p,
        "equivalent": bool(p < alpha),
        "ci_lower": lo,
        "ci_upper": hi,
    }


def jsonable(x):
    """JSON has no infinities: write them as the strings "inf" / "-inf"."""
    if isinstance(x, float) and math.isinf(x):
        return "inf" if x > 0 else "-inf"
    if isinstance(x, dict):
        return {k: jsonable(v) for k, v in x.items()}
    if isinstance(x, list):
        return [jsonable(v) for v in x]
    return x


def main():
    cases = []
    for name, d, ties in CASES:
        cases.append({
            "name": name,
            "diffs": d,
            "paired_t": [paired_t(d, level) for level in (0.95, 0.9)],
            "wilcoxon": wilcoxon(d, ties),
            "tost": [tost(d, m, 0.05) for m in (0.1, 0.25, 1.0)] + [tost(d, 0.25, 0.1)],
        })
    doc = {
        "provenance": {
            "script": "tools/stats_reference.py",
            "python": platform.python_version(),
            "numpy": np.__version__,
            "scipy": scipy.__version__,
            "statsmodels": statsmodels.__version__,
        },
        "t_distribution": t_distribution(),
        "cases": cases,
    }
    with open(OUT + ".tmp", "w") as f:
        json.dump(jsonable(doc), f, indent=1, allow_nan=False)
        f.write("\n")
    os.replace(OUT + ".tmp", OUT)
    print(f"wrote {os.path.relpath(OUT)}: {len(cases)} cases", file=sys.stderr)


if __name__ == "__main__":
    main()
