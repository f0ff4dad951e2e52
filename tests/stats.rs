//! The paired-difference statistics of `hdrsynth::stats` against scipy
//! (tests/data/stats_reference.json, written by tools/stats_reference.py) and hand-computed values.

use hdrsynth::stats::{
    PairedT, Tost, WilcoxonMethod, paired_t, student_t_cdf, student_t_quantile, tost_paired,
    wilcoxon_signed_rank,
};
use serde_json::Value;

const REL: f64 = 1e-9;

fn reference() -> Value {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/data/stats_reference.json"
    );
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{path}: {e}"));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{path}: {e}"))
}

/// A number of the reference file; infinities are written as "inf" / "-inf".
fn num(v: &Value) -> f64 {
    match v {
        Value::String(s) if s == "inf" => f64::INFINITY,
        Value::String(s) if s == "-inf" => f64::NEG_INFINITY,
        _ => v.as_f64().unwrap_or_else(|| panic!("not a number: {v}")),
    }
}

fn close(what: &str, got: f64, want: f64) {
    let ok = got == want || (got - want).abs() <= REL * got.abs().max(want.abs());
    assert!(
        ok,
        "{what}: got {got:e}, scipy {want:e} (rel {:e})",
        (got - want).abs() / want.abs()
    );
}

#[test]
fn t_distribution_matches_scipy() {
    let r = reference();
    let td = &r["t_distribution"];
    let cdf = td["cdf"].as_array().unwrap();
    assert!(cdf.len() > 100);
    for c in cdf {
        let (x, df) = (num(&c["x"]), num(&c["df"]));
        close(
            &format!("cdf({x}, {df})"),
            student_t_cdf(x, df),
            num(&c["cdf"]),
        );
    }
    let q = td["quantile"].as_array().unwrap();
    assert!(q.len() > 100);
    for c in q {
        let (p, df) = (num(&c["p"]), num(&c["df"]));
        let got = student_t_quantile(p, df);
        close(&format!("quantile({p}, {df})"), got, num(&c["quantile"]));
        // The quantile inverts the CDF on the side that carries the precision.
        let tail = if p < 0.5 { p } else { 1.0 - p };
        close(
            &format!("cdf(quantile({p}, {df}))"),
            student_t_cdf(-got.abs(), df),
            tail,
        );
    }
}

#[test]
fn paired_tests_match_scipy() {
    let r = reference();
    let cases = r["cases"].as_array().unwrap();
    assert!(cases.len() >= 15);
    let (mut exact, mut approx) = (0, 0);
    for c in cases {
        let name = c["name"].as_str().unwrap();
        let d: Vec<f64> = c["diffs"].as_array().unwrap().iter().map(num).collect();

        for e in c["paired_t"].as_array().unwrap() {
            let level = num(&e["level"]);
            let got = paired_t(&d, level).unwrap();
            let w = |k: &str| num(&e[k]);
            let tag = |k: &str| format!("{name} paired_t({level}) {k}");
            assert_eq!(got.n, d.len());
            close(&tag("mean"), got.mean, w("mean"));
            close(&tag("sd"), got.sd, w("sd"));
            close(&tag("se"), got.se, w("se"));
            close(&tag("t"), got.t, w("t"));
            close(&tag("p"), got.p, w("p"));
            close(&tag("ci_lower"), got.ci_lower, w("ci_lower"));
            close(&tag("ci_upper"), got.ci_upper, w("ci_upper"));
        }

        let e = &c["wilcoxon"];
        let got = wilcoxon_signed_rank(&d).unwrap();
        let tag = |k: &str| format!("{name} wilcoxon {k}");
        assert_eq!(got.n as u64, e["n"].as_u64().unwrap(), "{}", tag("n"));
        let method = match e["method"].as_str().unwrap() {
            "exact" => WilcoxonMethod::Exact,
            _ => WilcoxonMethod::Approx,
        };
        assert_eq!(got.method, method, "{}", tag("method"));
        close(&tag("statistic"), got.statistic, num(&e["statistic"]));
        close(&tag("w_plus"), got.w_plus, num(&e["w_plus"]));
        close(&tag("w_minus"), got.w_minus, num(&e["w_minus"]));
        close(&tag("p"), got.p, num(&e["p"]));
        match got.method {
            WilcoxonMethod::Exact => {
                exact += 1;
                assert!(got.z.is_none());
            }
            WilcoxonMethod::Approx => {
                approx += 1;
                close(&tag("z"), -got.z.unwrap().abs(), num(&e["zstatistic"]));
            }
        }

        for e in c["tost"].as_array().unwrap() {
            let (margin, alpha) = (num(&e["margin"]), num(&e["alpha"]));
            let got = tost_paired(&d, margin, alpha).unwrap();
            let w = |k: &str| num(&e[k]);
            let tag = |k: &str| format!("{name} tost({margin}, {alpha}) {k}");
            close(&tag("t_lower"), got.t_lower, w("t_lower"));
            close(&tag("p_lower"), got.p_lower, w("p_lower"));
            close(&tag("t_upper"), got.t_upper, w("t_upper"));
            close(&tag("p_upper"), got.p_upper, w("p_upper"));
            close(&tag("p"), got.p, w("p"));
            close(&tag("ci_lower"), got.ci_lower, w("ci_lower"));
            close(&tag("ci_upper"), got.ci_upper, w("ci_upper"));
            assert_eq!(got.equivalent, e["equivalent"].as_bool().unwrap());
            assert_eq!(
                got.equivalent,
                -margin < got.ci_lower && got.ci_upper < margin,
                "{}",
                tag("interval")
            );
        }
    }
    assert!(exact >= 5 && approx >= 5, "{exact} exact, {approx} approx");
}

#[test]
fn hand_computed_cases() {
    // d = [1, 2, 3, 4]: mean 2.5, Σ(d − mean)² = 5, sd = √(5/3), se = sd/2 = 0.6454972243679028,
    // t = 2.5/se = 3.872983346207417 (= √15). df = 3, t_{0.975,3} = 3.182446305284263
    // (tables), so the 95 % interval is 2.5 ± 2.0542581... = [0.4457418, 4.5542582].
    let r = paired_t(&[1.0, 2.0, 3.0, 4.0], 0.95).unwrap();
    assert_eq!(r.n, 4);
    assert!((r.mean - 2.5).abs() < 1e-15);
    assert!((r.t - 15f64.sqrt()).abs() < 1e-12);
    assert!((r.ci_upper - (2.5 + 3.182446305284263 * 0.6454972243679028)).abs() < 1e-9);
    // Two-sided p for df = 3 has the closed form
    // p = 1 − (2/π)·(atan(t/√3) + (t/√3)/(1 + t²/3)); t²/3 = 5: p = 1 − (2/π)(atan √5 + √5/6).
    let s5 = 5f64.sqrt();
    let p = 1.0 - 2.0 / std::f64::consts::PI * (s5.atan() + s5 / 6.0);
    assert!((r.p - p).abs() < 1e-12 * p, "{} vs {p}", r.p);

    // df = 1 is the Cauchy distribution: F(t) = ½ + atan(t)/π, quantile tan(π(p − ½)).
    for t in [-3.0, -0.5, 0.25, 7.0] {
        let f = 0.5 + f64::atan(t) / std::f64::consts::PI;
        assert!((student_t_cdf(t, 1.0) - f).abs() < 1e-14 * f.max(1e-300));
    }
    // Left tail of the Cauchy: F(t) = atan(−1/t)/π for t < 0, accurate where ½ + atan(t)/π is not.
    let f = (1.0f64 / 1e6).atan() / std::f64::consts::PI;
    assert!((student_t_cdf(-1e6, 1.0) - f).abs() < 1e-13 * f);
    assert!((student_t_quantile(0.975, 1.0) - (0.475 * std::f64::consts::PI).tan()).abs() < 1e-12);
    // df = 2: F(t) = ½ + t/(2√(2 + t²)).
    let f2 = |t: f64| 0.5 + t / (2.0 * (2.0 + t * t).sqrt());
    for t in [-2.5, 0.4, 6.0] {
        assert!((student_t_cdf(t, 2.0) - f2(t)).abs() < 1e-14);
    }

    // Wilcoxon d = [1, −2, 3, 4, 5]: ranks 1..5, W+ = 1 + 3 + 4 + 5 = 13, W− = 2, statistic 2.
    // Subsets of {1..5} with sum ≤ 2: {}, {1}, {2} → 3 of 32, so p = 2·3/32 = 0.1875.
    let w = wilcoxon_signed_rank(&[1.0, -2.0, 3.0, 4.0, 5.0]).unwrap();
    assert_eq!((w.w_plus, w.w_minus, w.statistic), (13.0, 2.0, 2.0));
    assert_eq!(w.method, WilcoxonMethod::Exact);
    assert_eq!(w.p, 0.1875);
    // All positive, n = 3: only the empty set has sum 0 of 8 → p = 2/8.
    assert_eq!(wilcoxon_signed_rank(&[0.5, 0.0, 1.5, 2.5]).unwrap().p, 0.25);
    // One tie, d = [1, 1, −3]: ranks 1.5, 1.5, 3; W+ = 3, W− = 3; n = 3, Σ(t³ − t) = 6,
    // σ² = (3·4·7 − 6/2)/24 = 3.375, z = (3 − 3)/σ = 0, p = 1.
    let w = wilcoxon_signed_rank(&[1.0, 1.0, -3.0]).unwrap();
    assert_eq!(w.method, WilcoxonMethod::Approx);
    assert_eq!((w.w_plus, w.z, w.p), (3.0, Some(0.0), 1.0));

    // TOST of [1, 2, 3, 4] within ±3 at α = 0.05: t_upper = (2.5 − 3)/se = −0.7746 → p ≈ 0.25,
    // not equivalent; the 90 % interval 2.5 ± t_{0.95,3}·se = 2.5 ± 2.353363434801823·se.
    let t = tost_paired(&[1.0, 2.0, 3.0, 4.0], 3.0, 0.05).unwrap();
    assert!(!t.equivalent && t.p > 0.2 && t.p == t.p_upper);
    assert!((t.ci_upper - (2.5 + 2.353363434801823 * 0.6454972243679028)).abs() < 1e-9);
}

#[test]
fn edge_cases() {
    // Too few or non-finite differences: None (rejected, never filtered).
    assert!(paired_t(&[], 0.95).is_none());
    assert!(paired_t(&[0.3], 0.95).is_none());
    assert!(paired_t(&[0.3, f64::NAN, 0.1], 0.95).is_none());
    assert!(paired_t(&[0.3, f64::INFINITY], 0.95).is_none());
    assert!(tost_paired(&[], 0.1, 0.05).is_none());
    assert!(tost_paired(&[0.3], 0.1, 0.05).is_none());
    assert!(tost_paired(&[0.3, f64::NAN], 0.1, 0.05).is_none());
    assert!(wilcoxon_signed_rank(&[]).is_none());
    assert!(wilcoxon_signed_rank(&[0.0, 0.0]).is_none());
    assert!(wilcoxon_signed_rank(&[0.3, f64::NAN]).is_none());
    // One non-zero difference: W+ ∈ {0, 1} equally likely, p = 2·min(1, ½) = 1.
    let w = wilcoxon_signed_rank(&[0.7]).unwrap();
    assert_eq!((w.n, w.p, w.statistic), (1, 1.0, 0.0));

    // All differences zero: no evidence of a difference.
    let z: PairedT = paired_t(&[0.0; 6], 0.95).unwrap();
    assert_eq!((z.mean, z.sd, z.t, z.p), (0.0, 0.0, 0.0, 1.0));
    assert_eq!((z.ci_lower, z.ci_upper), (0.0, 0.0));
    // Equal non-zero differences: t = −∞, p = 0, zero-width interval at the value.
    let c = paired_t(&[-0.1; 3], 0.9).unwrap();
    assert_eq!((c.mean, c.t, c.p), (-0.1, f64::NEG_INFINITY, 0.0));
    assert_eq!((c.ci_lower, c.ci_upper), (-0.1, -0.1));
    // Zero spread with the mean on the margin: that side's t is 0, p = ½, not equivalent.
    let t: Tost = tost_paired(&[0.25; 4], 0.25, 0.05).unwrap();
    assert_eq!((t.t_upper, t.p_upper, t.p_lower, t.p), (0.0, 0.5, 0.0, 0.5));
    assert!(!t.equivalent);
    assert!(tost_paired(&[0.25; 4], 0.3, 0.05).unwrap().equivalent);

    // Distribution edges.
    assert!(student_t_cdf(f64::NAN, 3.0).is_nan());
    assert!(student_t_cdf(1.0, 0.0).is_nan());
    assert_eq!(student_t_cdf(f64::NEG_INFINITY, 3.0), 0.0);
    assert_eq!(student_t_cdf(0.0, 3.0), 0.5);
    assert_eq!(student_t_quantile(0.0, 3.0), f64::NEG_INFINITY);
    assert_eq!(student_t_quantile(1.0, 3.0), f64::INFINITY);
    assert!(student_t_quantile(1.5, 3.0).is_nan());
    assert_eq!(student_t_quantile(0.5, 7.0), 0.0);
    // Huge tails stay finite and invert: df = 0.5 puts the 1e-200 quantile near 1e800 (beyond
    // f64), and the Cauchy 1e-300 quantile at −1/(π·1e-300).
    assert_eq!(student_t_quantile(1e-200, 0.5), f64::NEG_INFINITY);
    let q = student_t_quantile(1e-300, 1.0);
    let want = -1.0 / (std::f64::consts::PI * 1e-300);
    assert!((q - want).abs() < 1e-12 * want.abs(), "{q:e}");
    // Large degrees of freedom approach the normal: t_{0.975, 1e8} = 1.959964 + O(1e-8).
    assert!((student_t_quantile(0.975, 1e8) - 1.959963984540054).abs() < 1e-7);
}

#[test]
fn the_median_of_rounded_values_is_interpolated_within_its_class() {
    use hdrsynth::stats::lattice_abs_median;
    // |r| = 0, 0, 1, 1, 1, 2: the 3rd of 6 falls in class 1 = [0.5, 1.5), which holds three
    // values above the two of class 0: 0.5 + (3 − 2)/3 = 0.8333…
    let r = [0.0, -0.0, 1.0, -1.0, 1.0, 2.0];
    let got = lattice_abs_median(r.iter().copied(), 1.0);
    assert!((got - (0.5 + 1.0 / 3.0)).abs() < 1e-12, "{got}");
    // Class 0 is [0, 0.5): four of five zeros put the median at 0.5 · 2.5/4.
    let got = lattice_abs_median([0.0, 0.0, 0.0, 0.0, 3.0].into_iter(), 2.0);
    assert!((got - 2.0 * 0.5 * 2.5 / 4.0).abs() < 1e-12, "{got}");
    // A normal variable of σ 0.8 steps, rounded: its median |z| is 0.6745 σ = 0.5396 steps;
    // the plain median of the rounded values is 1 (85 % off); the interpolation, which takes
    // the density as flat within a class, is 5 % high at this σ (less at the several steps of
    // an Immerkær residual).
    // Quantiles of N(0, σ²) at (i + ½)/n by the library's inverse normal CDF.
    let n = 20_000;
    let z: Vec<f64> = (0..n)
        .map(|i| (0.8 * hdrsynth::stats::normal_quantile((i as f64 + 0.5) / n as f64)).round())
        .collect();
    let got = lattice_abs_median(z.iter().copied(), 1.0);
    assert!((got / (0.674_489_75 * 0.8) - 1.0).abs() < 0.06, "{got}");
}
