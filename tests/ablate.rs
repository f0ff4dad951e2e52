//! `hdrsynth ablate`: a 2×2 grid of tiny Network-1 cells produces the table (means that are the
//! cells' own evaluation means, paired differences that are the difference of means over the same
//! sets), skips finished cells, resumes a cell killed mid-training bit-identically, and refuses a
//! cell whose settings changed.

mod common;

use hdrsynth::eval::ablate::{self, AblateConfig, CellStatus};
use hdrsynth::io::{ExrPrecision, Image, write_exr};
use hdrsynth::sensor::profile::SensorProfile;
use hdrsynth::train::TrainOptions;
use hdrsynth::train::config::TrainConfig;
use std::collections::BTreeMap;
use std::path::Path;

const STEPS: u64 = 4;

fn train_toml(run: &Path, dataset: &Path, steps: u64, init: Option<&Path>) -> String {
    let mut t = format!(
        "[run]\nout = {run:?}\nseed = 3\nsteps = {steps}\ncheckpoint_every = 2\nlog_every = 1\n\
         keep_checkpoints = 5\n\
         [model]\nkind = \"blend_unet\"\nbase_width = 4\ndepth = 2\nbatch_norm = true\n\
         [data]\ndataset = {dataset:?}\npatch = 32\nbatch_size = 2\nworkers = 1\n\
         profile = \"pure\"\n[optim]\nlr = 1e-3\n"
    );
    if let Some(i) = init {
        t.push_str(&format!("[init]\ncheckpoint = {i:?}\n"));
    }
    t
}

/// Two small radiance maps (a tinted 12-stop ramp and a checker of bright and dark squares).
fn radiance(dir: &Path) {
    std::fs::create_dir_all(dir).expect("mkdir");
    let (w, h) = (48, 32);
    let ramp = Image::from_fn(w, h, |x, y| {
        let v = (x as f32 / (w - 1) as f32 * 12.0 - 8.0).exp2();
        let t = y as f32 / (h - 1) as f32;
        [v * (0.6 + 0.4 * t), v, v * (1.0 - 0.3 * t)]
    });
    let checker = Image::from_fn(w, h, |x, y| {
        let v = if (x / 8 + y / 8) % 2 == 0 { 4.0 } else { 0.02 };
        [v, v * 0.8, v * 0.6]
    });
    write_exr(&dir.join("ramp.exr"), &ramp, ExrPrecision::Float).expect("ramp");
    write_exr(&dir.join("checker.exr"), &checker, ExrPrecision::Float).expect("checker");
}

fn ablate_toml(root: &Path, base: &Path, net_p_lr: f64) -> String {
    let canon = SensorProfile::shipped_dir().join("canon_eos_550d.toml");
    format!(
        "title = \"tiny grid\"\nout = {:?}\nbase = {base:?}\n\
         [testset]\ndir = {:?}\nradiance = {:?}\nprofile = {canon:?}\n\
         [testset.options]\nisos = [100, 1600]\n\
         [eval]\nresamples = 200\ntile = 32\nreference = \"canon__low\"\n\
         [[rows]]\nname = \"pure\"\nlabel = \"Net_P\"\n\
         set = {{ data = {{ profile = \"pure\" }}, optim = {{ lr = {net_p_lr:e} }} }}\n\
         [[rows]]\nname = \"canon\"\nlabel = \"Net_S\"\n\
         set = {{ data = {{ profile = {canon:?} }} }}\n\
         [[columns]]\nname = \"low\"\nlabel = \"ISO 100\"\nset = {{ data = {{ isos = [100] }} }}\n\
         [[columns]]\nname = \"high\"\nlabel = \"ISO 1600\"\nset = {{ data = {{ isos = [1600] }} }}\n",
        root.join("grid"),
        root.join("testset"),
        root.join("radiance"),
    )
}

/// table.csv as (row, column, metric) → (mean, diff).
fn table(path: &Path) -> BTreeMap<(String, String, String), (f64, Option<f64>)> {
    let text = std::fs::read_to_string(path).expect("table.csv");
    let mut lines = text.lines();
    assert_eq!(
        lines.next(),
        Some("row,column,metric,n,mean,ci_lo,ci_hi,diff_vs_reference,diff_ci_lo,diff_ci_hi")
    );
    lines
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            let diff = (!f[7].is_empty()).then(|| f[7].parse().expect("diff"));
            (
                (f[0].into(), f[1].into(), f[2].into()),
                (f[4].parse().expect("mean"), diff),
            )
        })
        .collect()
}

/// Mean of a metric in a cell's own `eval/summary.csv` (written by `hdrsynth eval`'s code).
fn summary_mean(cell: &Path, metric: &str) -> f64 {
    let text = std::fs::read_to_string(cell.join("eval/summary.csv")).expect("summary.csv");
    let line = text
        .lines()
        .find(|l| l.starts_with(&format!("{metric},")))
        .expect("metric");
    line.split(',').nth(3).unwrap().parse().expect("mean")
}

#[test]
fn a_two_by_two_grid_makes_the_table_skips_finished_cells_and_resumes_a_killed_one() {
    let tmp = tempfile::tempdir().expect("tmp");
    let root = tmp.path();
    let data = root.join("train");
    common::generate(&data, 11, 3, (64, 48), "[-3.0, 0.0]");
    radiance(&root.join("radiance"));

    // The pretrained network every cell starts from.
    let pre = root.join("pretrain");
    let pre_cfg: TrainConfig =
        hdrsynth::config::parse_toml(&train_toml(&pre, &data, 2, None), Path::new("pre.toml"))
            .expect("pretrain config");
    hdrsynth::train::run(&pre_cfg, &TrainOptions::default()).expect("pretrain");

    let base = root.join("base.toml");
    std::fs::write(
        &base,
        train_toml(Path::new("unused"), &data, STEPS, Some(&pre)),
    )
    .expect("base");
    let cfg_path = root.join("grid.toml");
    std::fs::write(&cfg_path, ablate_toml(root, &base, 2e-3)).expect("grid");
    let cfg = AblateConfig::load(&cfg_path).expect("config");

    let first = ablate::run(&cfg, &cfg_path, false).expect("grid");
    assert_eq!(first.cells.len(), 4);
    assert!(
        first
            .cells
            .iter()
            .all(|c| c.status == CellStatus::Ran { resumed_at: None })
    );
    let grid = root.join("grid");
    let md = std::fs::read_to_string(grid.join("table.md")).expect("table.md");
    for want in [
        "tiny grid",
        "## PSNR-T",
        "## SSIM-L",
        "Net_P",
        "Net_S",
        "ISO 1600",
    ] {
        assert!(md.contains(want), "table.md lacks {want}:\n{md}");
    }
    assert!(!md.contains("not run yet"), "{md}");
    let t1 = table(&grid.join("table.csv"));
    assert_eq!(t1.len(), 4 * 4, "4 cells × 4 metrics");
    let cell = |r: &str, c: &str| grid.join("cells").join(format!("{r}__{c}"));
    for ((r, c, m), (mean, diff)) in &t1 {
        // 4 sets (2 scenes × 2 ISOs); the grid's mean is the cell evaluation's mean.
        let own = summary_mean(&cell(r, c), m);
        assert!((mean - own).abs() < 1e-9, "{r}/{c} {m}: {mean} vs {own}");
        // Paired over the same sets, the mean difference is the difference of the means.
        let reference = t1[&("canon".into(), "low".into(), m.clone())].0;
        match diff {
            None => assert_eq!((r.as_str(), c.as_str()), ("canon", "low")),
            Some(d) => assert!(
                (d - (mean - reference)).abs() < 1e-9,
                "{d} vs {mean}−{reference}"
            ),
        }
    }
    // Cells trained different data (pure vs a camera's colour and noise): different networks.
    assert_ne!(
        t1[&("pure".into(), "low".into(), "psnr_l".into())].0,
        t1[&("canon".into(), "high".into(), "psnr_l".into())].0
    );

    // Delete one cell; "kill" another mid-training: its final checkpoint and evaluation gone,
    // the step-2 checkpoint left.
    std::fs::remove_dir_all(cell("canon", "high")).expect("rm cell");
    let killed = cell("pure", "high");
    std::fs::remove_dir_all(killed.join("eval")).expect("rm eval");
    let ckpts = killed.join("run/checkpoints");
    std::fs::remove_dir_all(ckpts.join(format!("step-{STEPS:08}"))).expect("rm final");
    std::fs::write(ckpts.join("latest"), "step-00000002").expect("latest");

    let second = ablate::run(&cfg, &cfg_path, false).expect("rerun");
    let status: Vec<(&str, &CellStatus)> = second
        .cells
        .iter()
        .map(|c| (c.id.as_str(), &c.status))
        .collect();
    assert_eq!(
        status,
        vec![
            ("pure__low", &CellStatus::Kept),
            (
                "pure__high",
                &CellStatus::Ran {
                    resumed_at: Some(2)
                }
            ),
            ("canon__low", &CellStatus::Kept),
            ("canon__high", &CellStatus::Ran { resumed_at: None }),
        ]
    );
    // Resume is bit-identical and rerunning is deterministic: the same table.
    assert_eq!(t1, table(&grid.join("table.csv")));

    // A changed cell is refused, naming it, rather than reusing a stale result.
    std::fs::write(&cfg_path, ablate_toml(root, &base, 5e-3)).expect("grid");
    let changed = AblateConfig::load(&cfg_path).expect("config");
    let err = ablate::run(&changed, &cfg_path, false).expect_err("changed cell");
    let msg = err.to_string();
    assert!(msg.contains("pure__low") && msg.contains("delete"), "{msg}");
}

#[test]
fn a_grid_config_with_a_bad_axis_name_is_an_error_naming_the_file() {
    let tmp = tempfile::tempdir().expect("tmp");
    let path = tmp.path().join("bad.toml");
    std::fs::write(
        &path,
        "title = \"t\"\nout = \"o\"\nbase = \"b.toml\"\n[testset]\ndir = \"ts\"\n\
         [[rows]]\nname = \"a b\"\n",
    )
    .expect("write");
    let msg = AblateConfig::load(&path).expect_err("bad name").to_string();
    assert!(msg.contains("bad.toml") && msg.contains("'a b'"), "{msg}");
}

#[test]
fn the_shipped_experiment_configs_parse_and_resolve_their_cells() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    for (file, cells, training) in [
        ("exp1_network1.toml", 3, 2),
        ("exp2_network2.toml", 2, 1),
        ("exp3_network2_colour_iso.toml", 6, 6),
    ] {
        let path = root.join("configs/experiments").join(file);
        let mut cfg = AblateConfig::load(&path).expect(file);
        cfg.base = root.join(&cfg.base);
        assert_eq!(cfg.cells().len(), cells, "{file}");
        let tcs = ablate::train_configs(&cfg, &path).expect(file);
        assert_eq!(tcs.len(), training, "{file}");
        for tc in tcs {
            assert!(
                tc.init.is_some(),
                "{file}: every cell fine-tunes from a checkpoint"
            );
        }
    }
}
