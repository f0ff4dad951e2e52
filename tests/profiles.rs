//! The shipped sensor profiles: valid, honest about provenance, and different enough in colour
//! for the colour ablation; the chart-fitted Canon T agrees with Adobe's published matrix.

use hdrsynth::sensor::colour::chart::reference_linear_srgb;
use hdrsynth::sensor::colour::cie::delta_e_linear_srgb;
use hdrsynth::sensor::colour::fit::t_from_camera_xyz;
use hdrsynth::sensor::profile::{ProfileKind, SensorProfile};

fn shipped() -> Vec<(String, SensorProfile)> {
    let dir = SensorProfile::shipped_dir();
    let mut v: Vec<_> = std::fs::read_dir(&dir)
        .expect("configs/sensors")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .map(|p| {
            let prof = SensorProfile::load(&p).unwrap_or_else(|e| panic!("{e}"));
            (p.file_name().unwrap().to_string_lossy().into_owned(), prof)
        })
        .collect();
    v.sort_by(|a, b| a.0.cmp(&b.0));
    v
}

fn mat(p: &SensorProfile) -> [[f64; 3]; 3] {
    p.colour.as_ref().expect("colour").matrix
}

/// Mean ΔE00 over the 24 patches between two transforms of the reference chart (each
/// normalised so patch 22, neutral 5, has the same green: exposure differences excluded).
fn chart_delta_e(a: &[[f64; 3]; 3], b: &[[f64; 3]; 3]) -> f64 {
    let apply = |m: &[[f64; 3]; 3], c: [f64; 3]| -> [f64; 3] {
        std::array::from_fn(|r| m[r][0] * c[0] + m[r][1] * c[1] + m[r][2] * c[2])
    };
    let chart = reference_linear_srgb();
    let ka = 1.0 / apply(a, chart[21])[1];
    let kb = 1.0 / apply(b, chart[21])[1];
    let total: f64 = chart
        .iter()
        .map(|&c| {
            delta_e_linear_srgb(
                apply(a, c).map(|v| v * ka * 0.19),
                apply(b, c).map(|v| v * kb * 0.19),
            )
        })
        .sum();
    total / chart.len() as f64
}

#[test]
fn shipped_profiles_are_valid_and_sourced() {
    let all = shipped();
    let measured: Vec<_> = all
        .iter()
        .filter(|(_, p)| p.kind == ProfileKind::Measured)
        .collect();
    assert!(
        measured.len() >= 3,
        "need ≥ 3 real devices, have {}",
        measured.len()
    );
    let composite: Vec<_> = all
        .iter()
        .filter(|(_, p)| p.kind == ProfileKind::Composite)
        .collect();
    for (file, p) in measured.iter().chain(&composite) {
        assert!(p.colour.is_some(), "{file}: no colour calibration");
        assert!(!p.noise.is_empty(), "{file}: no noise calibration");
        for s in [
            &p.provenance.colour,
            &p.provenance.noise,
            &p.provenance.levels,
            &p.provenance.response,
        ] {
            assert!(s.len() > 20, "{file}: thin provenance '{s}'");
        }
        assert!(!p.name.to_lowercase().contains("example"));
    }
    let synthetic: Vec<_> = all
        .iter()
        .filter(|(_, p)| p.kind == ProfileKind::SyntheticExample)
        .collect();
    for (file, p) in synthetic {
        assert!(
            p.provenance.colour.contains("invented"),
            "{file} must say its numbers are invented"
        );
    }
}

/// Colour ablation pair: Canon EOS 550D (T fitted on a real chart capture) vs Samsung NX1000
/// (Adobe's matrix). Camera-raw colour models of real Bayer sensors are close; measured on
/// 2026-11-21: 550D–NX1000 2.79, 550D–WB2000 1.65, NX1000–WB2000 2.68 mean ΔE00, and the Canon
/// chart fit lies 2.88 from Adobe's own 550D matrix (a different illuminant and method).
#[test]
fn colour_ablation_profiles_differ_and_canon_fit_agrees_with_adobe() {
    let all = shipped();
    let get = |f: &str| all.iter().find(|(n, _)| n == f).map(|(_, p)| p).expect(f);
    let canon = mat(get("canon_eos_550d.toml"));
    // Adobe DNG Converter's 550D matrix (LibRaw colordata.cpp "EOS 550D").
    let adobe = t_from_camera_xyz(&[
        [0.6941, -0.1164, -0.0857],
        [-0.3825, 1.1597, 0.2534],
        [-0.0416, 0.1540, 0.6039],
    ])
    .expect("T");
    let fit_vs_adobe = chart_delta_e(&canon, &adobe);
    let pair = chart_delta_e(&canon, &mat(get("samsung_nx1000.toml")));
    for (a, pa) in &all {
        for (b, pb) in &all {
            // A variant of one camera (dslr_canon_550d_gamma22: the 550D with another
            // response) shares its colour model and says so in its provenance.
            let variant = pa.provenance.colour == pb.provenance.colour;
            if a < b && !variant {
                let d = chart_delta_e(&mat(pa), &mat(pb));
                eprintln!("{a} vs {b}: mean ΔE00 {d:.2}");
                assert!(
                    d > 1.0,
                    "{a} and {b} are nearly the same colour model ({d:.2})"
                );
            }
        }
    }
    eprintln!("Canon chart fit vs Adobe 550D: {fit_vs_adobe:.2}; ablation pair {pair:.2}");
    assert!(
        fit_vs_adobe < 3.5,
        "chart-fitted Canon T is {fit_vs_adobe:.2} ΔE00 from Adobe's"
    );
    assert!(pair > 2.5, "ablation pair differs by only {pair:.2} ΔE00");
}

/// The composite phone profile: darktable's OnePlus 6 noise, the Galaxy S9's
/// Adobe colour matrix, a 10-bit phone raw's levels; labelled composite, never measured.
#[test]
fn composite_phone_profile_is_what_it_says() {
    let all = shipped();
    let p = all
        .iter()
        .find(|(f, _)| f == "composite_phone.toml")
        .map(|(_, p)| p)
        .expect("configs/sensors/composite_phone.toml");
    assert_eq!(p.kind, ProfileKind::Composite);
    assert_eq!(p.kind.to_string(), "composite");
    assert!(p.name.contains("Composite"), "{}", p.name);
    // darktable noiseprofiles.json, "ONEPLUS A6003 iso 100" (a CSV line with b > 0: the
    // read-noise floor changes nothing).
    let n = &p.noise[0];
    assert_eq!(n.iso, 100.0);
    assert_eq!(
        n.a,
        [
            1.68690377957501e-05,
            6.39109629566731e-06,
            1.35016334361645e-05
        ]
    );
    assert_eq!(
        n.b,
        [
            3.29939136747073e-08,
            1.76344998034154e-08,
            3.56168148499628e-08
        ]
    );
    assert_eq!(
        p.noise.iter().map(|n| n.iso).collect::<Vec<_>>(),
        [100.0, 200.0, 400.0, 800.0, 1600.0, 3200.0, 6400.0]
    );
    assert!(p.provenance.noise.contains("ONEPLUS A6003"));
    assert!(p.provenance.noise.contains("no negative values"));
    // Galaxy S9 ColorMatrix (LibRaw colordata.cpp) ×1/10000 times sRGB→XYZ (IEC 61966-2-1,
    // 4 decimals), rows scaled to sum 1, computed by hand (Python, 2026-11-24):
    // row sums before scaling 0.5111194, 1.03948895, 0.70230785.
    let want = [
        [0.812209, 0.040952, 0.146838],
        [0.103551, 0.760709, 0.135740],
        [0.039905, 0.255811, 0.704284],
    ];
    let t = mat(p);
    for r in 0..3 {
        for c in 0..3 {
            assert!(
                (t[r][c] - want[r][c]).abs() < 1e-6,
                "T[{r}][{c}] = {} vs {}",
                t[r][c],
                want[r][c]
            );
        }
    }
    assert!(p.provenance.colour.contains("Galaxy S9"));
    assert!(p.provenance.colour.contains("13292,-6142,-1268"));
    assert_eq!(
        (
            p.levels.black_level,
            p.levels.white_level,
            p.levels.bit_depth
        ),
        (64.0, 1023.0, 10)
    );
    assert!(p.provenance.response.contains("assumption"));
    // Relative to full scale, the phone is noisier than the DSLR at the same ISO (darktable,
    // ISO 100: OnePlus 6 a_G 6.4e-6 vs Canon 550D 3.4e-6).
    let canon = &all
        .iter()
        .find(|(f, _)| f == "canon_eos_550d.toml")
        .unwrap()
        .1;
    assert!(n.a[1] > canon.noise[0].a[1]);
}

/// `SensorProfile::load_existing` (every calibration that updates a profile goes through it):
/// no file is None; a file that is not a profile is an error naming it, never overwritten.
#[test]
fn an_existing_file_that_is_not_a_profile_is_refused_not_overwritten() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("my_phone.toml");
    assert!(SensorProfile::load_existing(&path).unwrap().is_none());
    std::fs::write(&path, "not = [a profile").unwrap();
    let e = SensorProfile::load_existing(&path).unwrap_err().to_string();
    assert!(e.contains("my_phone.toml"), "{e}");
    assert!(e.contains("not a valid sensor profile"), "{e}");
    assert!(e.contains("not overwriting it"), "{e}");
    let refused = SensorProfile::load_or_create(&path, || -> hdrsynth::error::Result<_> {
        unreachable!("a file is there: nothing may be created over it")
    });
    assert!(refused.is_err());
    assert_eq!(std::fs::read_to_string(&path).unwrap(), "not = [a profile");
}

/// The one parser of a response named on the command line (`--response` of calibrate colour,
/// testset and diagnose): hand-written cases.
#[test]
fn responses_named_on_the_command_line() {
    use hdrsynth::sensor::profile::Response;
    assert_eq!("srgb".parse::<Response>(), Ok(Response::Srgb));
    assert_eq!(" SRGB ".parse::<Response>(), Ok(Response::Srgb));
    assert_eq!("linear".parse::<Response>(), Ok(Response::Linear));
    assert_eq!(
        "gamma:2.2".parse::<Response>(),
        Ok(Response::Gamma { gamma: 2.2 })
    );
    let err = |s: &str| s.parse::<Response>().unwrap_err();
    assert!(err("gamma:0").contains("gamma must be > 0"));
    assert!(err("gamma:-1").contains("gamma must be > 0"));
    assert!(err("gamma:x").contains("gamma 'x' is not a number"));
    assert!(err("filmic").contains("expected srgb, linear or gamma:G"));
}

/// A profile written before profiles held an exposure rule (`calibrate brackets` of the
/// Canon 550D stack, `--response srgb`, by the previous build) reads and writes back to the
/// same bytes; with a rule it gains exactly its `[metering]` table and provenance line, and
/// without it again is the old file.
#[test]
fn a_profile_round_trips_with_and_without_its_exposure_rule() {
    use hdrsynth::sensor::metering::Metering;
    let fixture = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/profiles/written_before_metering.toml");
    let old = std::fs::read_to_string(&fixture).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("p.toml");
    let mut p = SensorProfile::load(&fixture).unwrap();
    assert_eq!(p.metering, None);
    assert_eq!(p.provenance.metering, None);
    p.save(&path).unwrap();
    assert_eq!(std::fs::read_to_string(&path).unwrap(), old);

    let rule = Metering {
        mid_grey: 0.125,
        max_clipped: 0.03,
    };
    assert_eq!(p.set_metering(Some((rule, "by hand".into()))), None);
    p.save(&path).unwrap();
    // The old text with the provenance line after `response = …` and the table after
    // `[source_response]`, before the first `[[calibrated_on]]`.
    let response_line = old.lines().find(|l| l.starts_with("response = ")).unwrap();
    let want = old
        .replacen(
            &format!("{response_line}\n"),
            &format!("{response_line}\nmetering = \"by hand\"\n"),
            1,
        )
        .replacen(
            "[[calibrated_on]]",
            "[metering]\nmid_grey = 0.125\nmax_clipped = 0.03\n\n[[calibrated_on]]",
            1,
        );
    assert_ne!(want, old);
    assert_eq!(std::fs::read_to_string(&path).unwrap(), want);
    let back = SensorProfile::load(&path).unwrap();
    assert_eq!(back, p);
    assert_eq!(back.metering, Some(rule));
    assert_eq!(back.provenance.metering.as_deref(), Some("by hand"));

    let mut q = back;
    assert_eq!(q.set_metering(None), Some(rule));
    q.save(&path).unwrap();
    assert_eq!(std::fs::read_to_string(&path).unwrap(), old);
}

/// The rule's ranges are the training config's (one check), keyed as the file spells them;
/// a rule without its provenance, or provenance without a rule, is refused naming the file.
#[test]
fn a_profile_exposure_rule_is_checked_like_a_config_one() {
    let fixture = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/profiles/written_before_metering.toml");
    let old = std::fs::read_to_string(&fixture).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("edited.toml");
    let with = |provenance: &str, table: &str| {
        let response_line = old.lines().find(|l| l.starts_with("response = ")).unwrap();
        let text = old
            .replacen(
                &format!("{response_line}\n"),
                &format!("{response_line}\n{provenance}"),
                1,
            )
            .replacen("[[calibrated_on]]", &format!("{table}[[calibrated_on]]"), 1);
        std::fs::write(&path, text).unwrap();
        SensorProfile::load(&path).map_err(|e| e.to_string())
    };
    let line = "metering = \"by hand\"\n";
    let ok = with(line, "[metering]\nmid_grey = 0.2\n\n").unwrap();
    // A key left out takes the default, as in a config's `[data.metering]`.
    let m = ok.metering.unwrap();
    assert_eq!((m.mid_grey, m.max_clipped), (0.2, 0.02));
    for (table, key) in [
        ("[metering]\nmid_grey = 1.0\n\n", "metering.mid_grey"),
        ("[metering]\nmid_grey = 0.0\n\n", "metering.mid_grey"),
        ("[metering]\nmax_clipped = 0.5\n\n", "metering.max_clipped"),
        (
            "[metering]\nmax_clipped = -0.01\n\n",
            "metering.max_clipped",
        ),
    ] {
        let e = with(line, table).unwrap_err();
        assert!(e.contains("edited.toml") && e.contains(key), "{table}: {e}");
    }
    let e = with("", "[metering]\nmid_grey = 0.2\n\n").unwrap_err();
    assert!(
        e.contains("edited.toml") && e.contains("provenance.metering"),
        "{e}"
    );
    assert!(e.contains("missing"), "{e}");
    let e = with(line, "").unwrap_err();
    assert!(
        e.contains("provenance.metering") && e.contains("no [metering]"),
        "{e}"
    );
    let e = with(line, "[metering]\nmid_gray = 0.2\n\n").unwrap_err();
    assert!(e.contains("mid_gray"), "{e}");
}
