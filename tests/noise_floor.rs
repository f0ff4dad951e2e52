//! The read-noise floor for darktable's negative b and the noise table.
//!
//! darktable's Canon EOS 550D profile (set 1) has b < 0 at ISO 200–3200; kept verbatim, the
//! realism operator clamps a·x + b at 0 and the shadows get no noise at all. The two CSV rows
//! below are darktable's (noiseprofiles.json, CSV lines 760–761), so the test needs no shared
//! data.

use hdrsynth::io::Image;
use hdrsynth::sensor::darktable::{self, ImportRequest, NegativeRule, Query};
use hdrsynth::sensor::profile::{Levels, ProfileKind, Response, SensorProfile};
use hdrsynth::sensor::realism::{Realism, RealismOptions};

const CSV: &str = "maker,model,iso,a_R,a_G,a_B,b_R,b_G,b_B,profile_name
Canon,EOS 550D,100,3.42038078891161e-06,3.42038078891161e-06,3.42038078891161e-06,1.69357216945505e-07,1.69357216945505e-07,1.69357216945505e-07,Canon EOS 550D iso 100
Canon,EOS 550D,200,8.16755837136271e-06,8.16755837136271e-06,8.16755837136271e-06,-3.02248208072624e-07,-3.02248208072624e-07,-3.02248208072624e-07,Canon EOS 550D iso 200
";

fn import(dir: &std::path::Path, rule: NegativeRule) -> SensorProfile {
    let csv = dir.join("dt.csv");
    std::fs::write(&csv, CSV).unwrap();
    let out = dir.join(format!("{rule:?}.toml"));
    darktable::import(&ImportRequest {
        csv,
        query: Query {
            maker: "Canon".into(),
            model: "EOS 550D".into(),
            ..Query::default()
        },
        // The 550D DNG's levels: range 12944 DN.
        levels: Levels {
            black_level: 2056.0,
            white_level: 15000.0,
            bit_depth: 14,
        },
        levels_source: "test".into(),
        rule,
        out,
        name: None,
        kind: ProfileKind::Measured,
    })
    .unwrap()
    .profile
}

/// Sample variance in DN² of channel 0 of a flat frame at 0.5 % of white, ISO 200.
fn shadow_variance(p: &SensorProfile) -> (f64, f64) {
    let mut p = p.clone();
    p.source_response = Response::Linear;
    let mut o = RealismOptions::new(200.0);
    o.colour = false;
    let r = Realism::new(&p, &o).unwrap();
    let dn = r.to_dn(&Image::from_fn(256, 256, |_, _| [0.005; 3]), 7);
    let v: Vec<f64> = dn.data.iter().step_by(3).map(|&x| x as f64).collect();
    let n = v.len() as f64;
    let m = v.iter().sum::<f64>() / n;
    (
        v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0),
        n,
    )
}

#[test]
fn negative_b_leaves_read_noise_in_the_shadows() {
    let tmp = tempfile::tempdir().unwrap();
    let p = import(tmp.path(), NegativeRule::default());
    // ISO 200's b = −3.02e-7 becomes ISO 100's b = 1.69357216945505e-7 (the largest positive b
    // at a lower ISO), far above the quantisation floor 1/(12·12944²) = 4.97e-10.
    assert_eq!(p.noise[1].b, [1.69357216945505e-7; 3]);
    assert_eq!(p.noise[1].a, [8.16755837136271e-6; 3]);
    assert!(p.provenance.noise.contains(
        "ISO 200 b_R = -3.02248208072624e-7 (line 3) → 1.69357216945505e-7 (b_R at ISO 100)"
    ));
    // By hand: x = 0.005: σ²_x = 8.16755837136271e-6·0.005 + 1.69357216945505e-7
    // = 2.10195e-7; in DN² ·12944² = 35.2176, plus 1/12 of rounding to integer DN = 35.3009.
    let want = 35.30090505965659;
    let (var, n) = shadow_variance(&p);
    let se = want * (2.0 / (n - 1.0)).sqrt();
    assert!(
        (var - want).abs() < 4.0 * se,
        "variance {var} DN² vs {want} (±{se})"
    );
    // The verbatim rule is still there, and shows the defect: a·x + b < 0 at 0.5 % → a
    // constant frame.
    let v = import(tmp.path(), NegativeRule::Verbatim);
    assert_eq!(v.noise[1].b, [-3.02248208072624e-7; 3]);
    assert_eq!(shadow_variance(&v).0, 0.0);
}

#[test]
fn quantisation_floor_without_a_lower_positive_b() {
    let tmp = tempfile::tempdir().unwrap();
    // Only the ISO 200 row: nothing lower, so b = 1/(12·12944²) = 4.9737e-10.
    let csv = tmp.path().join("dt.csv");
    let one: String = CSV
        .lines()
        .enumerate()
        .filter(|(i, _)| *i != 1)
        .map(|(_, l)| format!("{l}\n"))
        .collect();
    std::fs::write(&csv, one).unwrap();
    let out = tmp.path().join("p.toml");
    let p = darktable::import(&ImportRequest {
        csv,
        query: Query {
            maker: "Canon".into(),
            model: "EOS 550D".into(),
            ..Query::default()
        },
        levels: Levels {
            black_level: 2056.0,
            white_level: 15000.0,
            bit_depth: 14,
        },
        levels_source: "test".into(),
        rule: NegativeRule::Floor,
        out,
        name: None,
        kind: ProfileKind::Measured,
    })
    .unwrap()
    .profile;
    let q = 1.0 / (12.0 * 12944.0f64 * 12944.0);
    for b in p.noise[0].b {
        assert!((b - q).abs() <= 1e-15 * q, "{b} vs {q}");
    }
    assert!(p.provenance.noise.contains("(quantisation floor)"));
}

/// σ in 8-bit codes of the shipped Canon EOS 550D profile (sRGB device response), by hand:
/// σ_code = s'(x)·√(a·x + b)·255 with s'(x) = 1.055/2.4·x^(1/2.4 − 1) (IEC 61966-2-1 above
/// 0.0031308). ISO 100: a = 3.42038078891161e-6, b = 1.69357216945505e-7 (darktable, positive:
/// unchanged); ISO 200: a = 8.16755837136271e-6 and b replaced by ISO 100's.
///   ISO 100, x = 0.01: √(2.03561e-7) = 4.5118e-4; s' = 6.4522 → 0.74233
///   ISO 100, x = 0.10: √(5.11395e-7) = 7.1512e-4; s' = 1.6841 → 0.30711
///   ISO 200, x = 0.01: √(2.51033e-7) = 5.0103e-4 → 0.82435;  x = 0.10: → 0.42646
#[test]
fn noise_table_matches_hand_computed_values() {
    let path = SensorProfile::shipped_dir().join("canon_eos_550d.toml");
    let p = SensorProfile::load(&path).unwrap();
    let t = p.noise_table(&[0.01, 0.1], 255.0).unwrap();
    let want = [
        (100.0, 0.7423272090677049, 0.30710939048848995),
        (200.0, 0.8243531479096463, 0.4264597870234608),
    ];
    for (iso, s1, s10) in want {
        let row = t.iter().find(|r| r.iso == iso).unwrap();
        for c in 0..3 {
            assert!(
                (row.sigma[0][c] - s1).abs() < 1e-9,
                "ISO {iso} 1 %: {:?}",
                row.sigma
            );
            assert!(
                (row.sigma[1][c] - s10).abs() < 1e-9,
                "ISO {iso} 10 %: {:?}",
                row.sigma
            );
        }
    }
    // Every shipped ISO has noise at 1 % of white after the floor rule.
    for r in &t {
        assert!(
            r.sigma[0].iter().all(|s| *s > 0.1),
            "ISO {}: {:?}",
            r.iso,
            r.sigma
        );
    }
    let md = p.noise_table_markdown(&[0.01, 0.1]).unwrap();
    assert!(
        md.contains("| 100 | 0.74, 0.74, 0.74 | 0.31, 0.31, 0.31 |"),
        "{md}"
    );
    assert!(md.contains("(measured)"));
    assert!(p.noise_table(&[0.0], 255.0).is_err());
}
