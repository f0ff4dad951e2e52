//! `hdrsynth ablate`: a 2×2 grid of tiny Network-1 cells produces the table (means that are the
//! cells' own evaluation means, paired differences that are the difference of means over the same
//! sets), skips finished cells, resumes a cell killed mid-training bit-identically, and refuses a
//! cell whose settings changed. The statistics resample scenes, not sets, and seeds (hand-made
//! per-set scores); a 2-seed grid trains every trained cell per seed; a control cell trains the
//! pretrained network on its own pretraining data.

mod common;

use burn::module::{Module, ModuleVisitor, Param};
use burn::tensor::{Device, Tensor};
use hdrsynth::experiments::ablate::{self, AblateConfig, CellStatus};
use hdrsynth::io::{ExrPrecision, Image, write_exr};
use hdrsynth::models::ModelConfig;
use hdrsynth::models::seeded_init;
use hdrsynth::sensor::profile::SensorProfile;
use hdrsynth::stats::{bootstrap_ci, bootstrap_crossed};
use hdrsynth::train::TrainOptions;
use hdrsynth::train::checkpoint;
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
        Some(
            "row,column,metric,n,mean,ci_lo,ci_hi,diff_vs_reference,diff_ci_lo,diff_ci_hi,\
             n_seeds,n_scenes,seeds_positive,diff_n_seeds,diff_t_lo,diff_t_hi,diff_t_p,\
             diff_wilcoxon_p,diff_tost_margin,diff_tost_p,n_pretrain_seeds"
        )
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
    let count = |m: &str| t1.keys().filter(|k| k.2 == m).count();
    for m in ["psnr_t", "psnr_l", "ssim_t", "ssim_l", "delta_e2000"] {
        assert_eq!(count(m), 4, "4 cells of {m}");
    }
    // PSNR-T dark only for cells whose sets hold enough under-exposed pixels.
    assert_eq!(t1.len(), 5 * 4 + count("psnr_t_dark"));
    let cell = |r: &str, c: &str| grid.join("cells").join(format!("{r}__{c}"));
    // PSNR-T dark averages per scene over the sets that have it, which is not the summary's
    // mean over sets; the other five are the same mean over the 4 sets.
    for ((r, c, m), (mean, diff)) in t1.iter().filter(|(k, _)| k.2 != "psnr_t_dark") {
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

    // Two cells at a time: the same table and the same weights, cell by cell.
    let at_once = AblateConfig {
        out: root.join("grid2"),
        jobs: 2,
        ..cfg.clone()
    };
    let run2 = ablate::run(&at_once, &cfg_path, false).expect("two at once");
    let ids: Vec<&str> = run2.cells.iter().map(|c| c.id.as_str()).collect();
    assert_eq!(
        ids,
        ["pure__low", "pure__high", "canon__low", "canon__high"]
    );
    assert_eq!(t1, table(&root.join("grid2/table.csv")));
    for id in ids {
        let weights = |g: &str| {
            let run = root.join(g).join("cells").join(id).join("run");
            let dir = hdrsynth::train::checkpoint::resolve(&run).expect("checkpoint");
            std::fs::read(dir.join("model.bpk")).expect("model")
        };
        assert!(weights("grid") == weights("grid2"), "{id}: weights differ");
    }

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
        ("exp1_network1.toml", 3, 2 * 3),
        ("exp2_network2.toml", 2, 3),
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

/// The CPU-scale experiments (configs/experiments/cpu, tools/cpu_experiments.sh): every training
/// and generation config validates, every ablation has the cells and seeds docs/experiments.md
/// reports, and each trained cell starts from the pretraining its config names.
#[test]
fn the_cpu_scale_experiment_configs_parse_and_resolve_their_cells() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let dir = root.join("configs/experiments/cpu");
    for file in ["data_net1.toml", "data_net1_val.toml", "data_net2.toml"] {
        let g = hdrsynth::data::generate::GenerateConfig::load(&dir.join(file)).expect(file);
        g.validate().expect(file);
    }
    for (file, init) in [
        ("net1_pretrain.toml", None),
        ("net1_pretrain_literal.toml", None),
        ("net2_pretrain.toml", None),
        ("net1_finetune.toml", Some("runs/cpu/net1_pretrain")),
        ("net2_finetune.toml", Some("runs/cpu/net2_pretrain")),
    ] {
        let t = TrainConfig::load(&dir.join(file)).expect(file);
        let got = t.init.as_ref().and_then(|i| i.checkpoint.as_ref());
        assert_eq!(got.map(|p| p.as_path()), init.map(Path::new), "{file}");
    }
    // (file, cells, trained cells × seeds)
    for (file, cells, trained) in [
        ("exp1_network1.toml", 4, 3 * 3),
        ("exp2_network2.toml", 4, 3 * 3),
        ("exp3_network2_colour_iso.toml", 6, 6 * 3),
        ("exp2_phone_b.toml", 4, 3 * 3),
        ("exp3b_what_the_gain_is.toml", 4, 4 * 3),
    ] {
        let path = dir.join(file);
        let cfg = AblateConfig::load(&path).expect(file);
        assert_eq!(cfg.cells().len(), cells, "{file}");
        let runs: usize = cfg
            .cells()
            .into_iter()
            .map(|(r, c)| cfg.cell_seeds(r, c).into_iter().flatten().count())
            .sum();
        assert_eq!(runs, trained, "{file}");
    }
}

// ---------------------------------------------------------------------------------------------
// Statistics on hand-made scores (no training)

/// table.csv (or table_seeds.csv) as one map per line, by column name.
fn csv_rows(path: &Path) -> Vec<BTreeMap<String, String>> {
    let text = std::fs::read_to_string(path).expect("csv");
    let mut lines = text.lines();
    let header: Vec<String> = lines
        .next()
        .expect("header")
        .split(',')
        .map(String::from)
        .collect();
    lines
        .map(|l| {
            header
                .iter()
                .cloned()
                .zip(l.split(',').map(String::from))
                .collect()
        })
        .collect()
}

fn find_row<'a>(
    rows: &'a [BTreeMap<String, String>],
    want: &[(&str, &str)],
) -> &'a BTreeMap<String, String> {
    rows.iter()
        .find(|r| want.iter().all(|(k, v)| r[*k] == *v))
        .unwrap_or_else(|| panic!("no row {want:?}"))
}

fn num(row: &BTreeMap<String, String>, key: &str) -> f64 {
    row[key]
        .parse()
        .unwrap_or_else(|_| panic!("{key} = '{}'", row[key]))
}

/// A cell evaluation's per-set scores as `hdrsynth eval` writes them; `psnr_t` is `v`, every
/// other metric `v / 100`.
fn write_scores(eval: &Path, sets: &[(&str, f64)]) {
    std::fs::create_dir_all(eval).expect("mkdir");
    let mut csv =
        String::from("set,psnr_l,psnr_t,ssim_l,ssim_t,pu21_psnr,pu21_ssim,width,height,seconds\n");
    for (set, v) in sets {
        let o = v / 100.0;
        csv.push_str(&format!("{set},{o},{v},{o},{o},{o},{o},8,8,0\n"));
    }
    std::fs::write(eval.join("per_image.csv"), csv).expect("per_image");
    std::fs::write(eval.join("summary.csv"), "metric\n").expect("summary");
}

fn grid_config(root: &Path, seeds: &str, rows: &str) -> AblateConfig {
    let path = root.join("grid.toml");
    std::fs::write(
        &path,
        format!(
            "title = \"t\"\nout = {:?}\nbase = \"unused.toml\"\n{seeds}\n\
             [testset]\ndir = {:?}\n[eval]\nresamples = 400\nseed = 7\n{rows}",
            root.join("grid"),
            root.join("testset"),
        ),
    )
    .expect("grid.toml");
    AblateConfig::load(&path).expect("config")
}

#[test]
fn the_interval_resamples_scenes_so_a_scene_seen_twice_counts_once() {
    let rows = "[[rows]]\nname = \"a\"\ntrain = false\n[[rows]]\nname = \"b\"\ntrain = false\n";
    let tables: Vec<_> = [true, false]
        .into_iter()
        .map(|twice| {
            let tmp = tempfile::tempdir().expect("tmp");
            let cfg = grid_config(tmp.path(), "", rows);
            // Scene x at two ISOs with identical scores, or at one ISO; y and z at one ISO.
            let mut a = vec![("x_iso100", 30.0), ("y_iso100", 24.0), ("z_iso100", 35.0)];
            let mut b = vec![("x_iso100", 31.0), ("y_iso100", 24.5), ("z_iso100", 38.0)];
            if twice {
                a.push(("x_iso800", 30.0));
                b.push(("x_iso800", 31.0));
            }
            write_scores(&cfg.cell_dir(0, None).join("eval"), &a);
            write_scores(&cfg.cell_dir(1, None).join("eval"), &b);
            ablate::write_table(&cfg).expect("table");
            csv_rows(&tmp.path().join("grid/table.csv"))
        })
        .collect();
    for key in [
        "mean",
        "ci_lo",
        "ci_hi",
        "diff_vs_reference",
        "diff_ci_lo",
        "diff_ci_hi",
    ] {
        let twice = num(
            find_row(&tables[0], &[("row", "b"), ("metric", "psnr_t")]),
            key,
        );
        let once = num(
            find_row(&tables[1], &[("row", "b"), ("metric", "psnr_t")]),
            key,
        );
        assert_eq!(
            twice, once,
            "{key}: a scene's second identical set changed it"
        );
    }
    let b = find_row(&tables[0], &[("row", "b"), ("metric", "psnr_t")]);
    assert_eq!((b["n"].as_str(), b["n_scenes"].as_str()), ("4", "3"));
    // The interval is the ordinary bootstrap of the three scene means (metrics' own function,
    // the same resample seeds), and the mean is the hand-computed mean of the scene means.
    let (m, lo, hi) = bootstrap_ci(&[31.0, 24.5, 38.0], 400, 7, 0.95);
    assert_eq!(
        (num(b, "mean"), num(b, "ci_lo"), num(b, "ci_hi")),
        (m, lo, hi)
    );
    assert!((m - 93.5 / 3.0).abs() < 1e-12);
    assert!(
        (num(b, "diff_vs_reference") - 4.5 / 3.0).abs() < 1e-12,
        "(1 + 0.5 + 3) / 3"
    );
}

#[test]
fn scenes_come_from_the_recipe_then_the_set_names_then_the_sets_themselves() {
    let tmp = tempfile::tempdir().expect("tmp");
    // A recipe whose scene name itself ends like an ISO tag: only the recipe can tell.
    std::fs::write(
        tmp.path().join("testset.toml"),
        "format = \"hdrsynth-testset/1\"\n[options]\nisos = [100.0, 800.0]\n\
         [[scenes]]\nname = \"desk\"\nfile = \"desk.exr\"\n\
         [[scenes]]\nname = \"lab\"\nfile = \"lab_iso100.exr\"\n",
    )
    .expect("recipe");
    let sets = [
        "desk_iso100",
        "desk_iso800",
        "lab_iso100",
        "kitchen_iso3200",
        "001",
        "x_iso",
    ];
    let scenes = hdrsynth::data::testset::scenes_of_sets(tmp.path(), sets).expect("scenes");
    let got: Vec<&str> = sets.iter().map(|s| scenes[*s].as_str()).collect();
    assert_eq!(got, ["desk", "desk", "lab", "kitchen", "001", "x_iso"]);
    std::fs::write(tmp.path().join("testset.toml"), "scenes = 3\n").expect("bad recipe");
    let msg = hdrsynth::data::testset::scenes_of_sets(tmp.path(), sets)
        .expect_err("bad recipe")
        .to_string();
    assert!(msg.contains("testset.toml"), "{msg}");
}

#[test]
fn the_two_level_bootstrap_matches_hand_computed_intervals() {
    // Two seeds × two scenes, one level constant: resampling the other gives means 0, ½, 1 with
    // probabilities ¼, ½, ¼, so the 2.5 % and 97.5 % percentiles are 0 and 1.
    let seed_only = vec![vec![0.0, 0.0], vec![1.0, 1.0]];
    let scene_only = vec![vec![0.0, 1.0], vec![0.0, 1.0]];
    for v in [&seed_only, &scene_only] {
        let (m, lo, hi) = bootstrap_crossed(v, 2000, 1, 0.95);
        assert_eq!((m, lo, hi), (0.5, 0.0, 1.0), "{v:?}");
    }
    // One seed: exactly the one-level bootstrap of the scenes.
    let row = vec![3.0, 1.0, 4.0, 1.5, 9.0];
    assert_eq!(
        bootstrap_crossed(std::slice::from_ref(&row), 500, 3, 0.9),
        bootstrap_ci(&row, 500, 3, 0.9)
    );
    // Identical seeds: the mean of one seed, 18.5 / 5.
    let (m, lo, hi) = bootstrap_crossed(&[row.clone(), row.clone(), row], 500, 3, 0.9);
    assert!(
        (m - 3.7).abs() < 1e-12 && lo < m && m < hi,
        "{m} [{lo}, {hi}]"
    );
}

#[test]
fn seeds_are_paired_counted_and_written_per_seed() {
    let tmp = tempfile::tempdir().expect("tmp");
    let cfg = grid_config(
        tmp.path(),
        "seeds = [1, 2, 3]",
        "[[rows]]\nname = \"net_o\"\ntrain = false\n[[rows]]\nname = \"net_s\"\n",
    );
    // Net_O: evaluated once. Net_S: per seed, every set scores Net_O + δ(seed).
    let base = [
        ("x_iso100", 30.0),
        ("x_iso800", 28.0),
        ("y_iso100", 20.0),
        ("y_iso800", 22.0),
    ];
    write_scores(&cfg.cell_dir(0, None).join("eval"), &base);
    for (seed, delta) in [(1, 1.0), (2, 2.0), (3, -0.5)] {
        let sets: Vec<(&str, f64)> = base.iter().map(|(s, v)| (*s, v + delta)).collect();
        write_scores(&cfg.unit_dir(1, None, Some(seed)).join("eval"), &sets);
    }
    let md = ablate::write_table(&cfg).expect("table");
    let t = csv_rows(&tmp.path().join("grid/table.csv"));
    let s = find_row(&t, &[("row", "net_s"), ("metric", "psnr_t")]);
    // Scene means 29 and 21 for Net_O (25 overall); Net_S per seed 25 + δ.
    let per_seed = [26.0, 27.0, 24.5];
    assert!((num(s, "mean") - per_seed.iter().sum::<f64>() / 3.0).abs() < 1e-12);
    assert!((num(s, "diff_vs_reference") - 2.5 / 3.0).abs() < 1e-12);
    assert_eq!(s["seeds_positive"], "2");
    assert_eq!(
        (
            s["n_seeds"].as_str(),
            s["n_scenes"].as_str(),
            s["diff_n_seeds"].as_str()
        ),
        ("3", "2", "3")
    );
    let o = find_row(&t, &[("row", "net_o"), ("metric", "psnr_t")]);
    assert_eq!(
        (o["n_seeds"].as_str(), o["seeds_positive"].as_str()),
        ("1", "")
    );
    assert!(
        md.contains("(2/3)"),
        "the sign holds in 2 of 3 seeds:\n{md}"
    );
    // The difference is the same for every scene within a seed: only the seed level varies,
    // so the interval lies within the seeds' differences −0.5 … 2.
    assert!(num(s, "diff_ci_lo") >= -0.5 && num(s, "diff_ci_hi") <= 2.0);
    assert!(
        num(s, "diff_ci_lo") < 0.0,
        "one seed of three goes the other way"
    );

    let ps = csv_rows(&tmp.path().join("grid/table_seeds.csv"));
    for (seed, mean, diff) in [("1", 26.0, 1.0), ("2", 27.0, 2.0), ("3", 24.5, -0.5)] {
        let r = find_row(
            &ps,
            &[("row", "net_s"), ("seed", seed), ("metric", "psnr_t")],
        );
        assert_eq!((num(r, "mean"), num(r, "diff_vs_reference")), (mean, diff));
        let r = find_row(
            &ps,
            &[("row", "net_o"), ("seed", seed), ("metric", "psnr_t")],
        );
        assert_eq!(num(r, "mean"), 25.0, "Net_O serves every seed");
    }
}

/// With ≥ 10 scenes the Δ gets the paired tests over scenes, each scene's Δ the mean over the
/// seeds; with fewer, means only (no interval, no test, no "*").
#[test]
fn paired_tests_use_the_scene_means_over_seeds_and_need_ten_scenes() {
    let rows = "[[rows]]\nname = \"a\"\n[[rows]]\nname = \"b\"\n";
    let tmp = tempfile::tempdir().expect("tmp");
    let cfg = grid_config(tmp.path(), "seeds = [1, 2]", rows);
    // 12 scenes at two ISOs. b − a on scene j is (j − 5.5) + 1 in seed 1 and (j − 5.5) + 1 ± 0.25
    // in seed 2 by ISO, so the scene means over ISOs and seeds are d_j = j − 4.5.
    for seed in [1u64, 2] {
        let (mut a, mut b) = (Vec::new(), Vec::new());
        let names: Vec<(String, String)> = (0..12)
            .map(|j| (format!("s{j:02}_iso100"), format!("s{j:02}_iso800")))
            .collect();
        for (j, (lo, hi)) in names.iter().enumerate() {
            let d = j as f64 - 4.5;
            let wobble = if seed == 2 { 0.25 } else { 0.0 };
            a.push((lo.as_str(), 20.0 + j as f64));
            a.push((hi.as_str(), 18.0 + j as f64));
            b.push((lo.as_str(), 20.0 + j as f64 + d + wobble));
            b.push((hi.as_str(), 18.0 + j as f64 + d - wobble));
        }
        write_scores(&cfg.unit_dir(0, None, Some(seed)).join("eval"), &a);
        write_scores(&cfg.unit_dir(1, None, Some(seed)).join("eval"), &b);
    }
    let md = ablate::write_table(&cfg).expect("table");
    let t = csv_rows(&tmp.path().join("grid/table.csv"));
    let b = find_row(&t, &[("row", "b"), ("metric", "psnr_t")]);
    assert_eq!(b["n_scenes"], "12");
    // Hand-computed: mean 1, sd √13 (Σ (j − 5.5)² = 143 over 11), se √13 / √12, and Student's
    // t quantile t_{0.975, 11} = 2.200985160082949.
    let se = 13f64.sqrt() / 12f64.sqrt();
    let q = 2.200985160082949;
    assert!((num(b, "diff_vs_reference") - 1.0).abs() < 1e-12);
    assert!((num(b, "diff_t_lo") - (1.0 - q * se)).abs() < 1e-9, "{b:?}");
    assert!((num(b, "diff_t_hi") - (1.0 + q * se)).abs() < 1e-9, "{b:?}");
    assert_eq!(num(b, "diff_tost_margin"), 0.2);
    let p = num(b, "diff_wilcoxon_p");
    assert!(p > 0.05 && p < 1.0, "{p}");
    assert!(md.contains("Wilcoxon"), "{md}");

    // Three scenes: means only.
    let tmp = tempfile::tempdir().expect("tmp");
    let cfg = grid_config(
        tmp.path(),
        "",
        "[[rows]]\nname = \"a\"\ntrain = false\n[[rows]]\nname = \"b\"\ntrain = false\n",
    );
    write_scores(
        &cfg.cell_dir(0, None).join("eval"),
        &[("x_iso100", 1.0), ("y_iso100", 2.0), ("z_iso100", 3.0)],
    );
    write_scores(
        &cfg.cell_dir(1, None).join("eval"),
        &[("x_iso100", 5.0), ("y_iso100", 6.0), ("z_iso100", 8.0)],
    );
    let md = ablate::write_table(&cfg).expect("table");
    let t = csv_rows(&tmp.path().join("grid/table.csv"));
    let b = find_row(&t, &[("row", "b"), ("metric", "psnr_t")]);
    assert_eq!(
        (b["diff_t_lo"].as_str(), b["diff_wilcoxon_p"].as_str()),
        ("", "")
    );
    assert!(
        md.contains("means only") && md.contains("| b | +4.33 |"),
        "{md}"
    );
    assert!(
        md.contains("| b | 6.33 |"),
        "a mean without an interval:\n{md}"
    );
}

/// Per-seed pretraining replaces the base's `[init]` per seed and makes cells that do not train
/// run per seed; per-seed test noise gives each seed its own test set folder; an `also` test set
/// gets its own eval folder and table.
#[test]
fn per_seed_pretraining_and_test_noise_resolve_per_seed() {
    let tmp = tempfile::tempdir().expect("tmp");
    let root = tmp.path();
    let base = root.join("base.toml");
    std::fs::write(
        &base,
        train_toml(
            Path::new("unused"),
            &root.join("data"),
            2,
            Some(Path::new("/pre/one")),
        ),
    )
    .expect("base");
    let canon = SensorProfile::shipped_dir().join("canon_eos_550d.toml");
    let path = root.join("grid.toml");
    let text = format!(
        "title = \"t\"\nout = {:?}\nbase = {base:?}\nseeds = [1, 2]\n\
         pretrained_per_seed = \"/pre/seed{{seed}}\"\n\
         [testset]\ndir = \"ts\"\nradiance = \"rad\"\nprofile = {canon:?}\nnoise_per_seed = true\n\
         [[also]]\nname = \"real\"\ndir = \"real_ts\"\n\
         [[rows]]\nname = \"net_o\"\ntrain = false\n[[rows]]\nname = \"net_s\"\n",
        root.join("grid")
    );
    std::fs::write(&path, &text).expect("grid");
    let cfg = AblateConfig::load(&path).expect("config");
    assert_eq!(
        cfg.cell_seeds(0, None),
        [Some(1), Some(2)],
        "Net_O per seed"
    );
    let inits: Vec<String> = ablate::train_configs(&cfg, &path)
        .expect("plans")
        .iter()
        .map(|c| {
            c.init
                .as_ref()
                .and_then(|i| i.checkpoint.clone())
                .expect("init")
                .display()
                .to_string()
        })
        .collect();
    assert_eq!(inits, ["/pre/seed1", "/pre/seed2"]);
    assert_eq!(cfg.testset.dir_for(Some(2)), Path::new("ts/seed2"));
    assert_eq!(cfg.also[0].dir_for(Some(2)), Path::new("real_ts"));

    // The `also` table reads eval_real/.
    for seed in [1u64, 2] {
        for (r, v) in [(0, 10.0), (1, 12.0)] {
            write_scores(
                &cfg.unit_dir(r, None, Some(seed)).join("eval_real"),
                &[("room", v + seed as f64)],
            );
        }
    }
    let md = ablate::write_table(&cfg).expect("tables");
    let t = csv_rows(&root.join("grid/table_real.csv"));
    let s = find_row(&t, &[("row", "net_s"), ("metric", "psnr_t")]);
    assert_eq!((num(s, "mean"), num(s, "diff_vs_reference")), (13.5, 2.0));
    assert!(md.contains("— real"), "{md}");

    // Refused: per-seed noise without radiance, per-seed pretraining without {seed}, an `also`
    // without a name.
    for (bad, what) in [
        (
            text.replace(&format!("radiance = \"rad\"\nprofile = {canon:?}\n"), ""),
            "noise_per_seed",
        ),
        (text.replace("seed{seed}", "fixed"), "pretrained_per_seed"),
        (text.replace("name = \"real\"\n", ""), "name"),
    ] {
        std::fs::write(&path, &bad).expect("bad");
        let msg = AblateConfig::load(&path).expect_err(what).to_string();
        assert!(msg.contains(what), "{what}: {msg}");
    }
}

#[test]
fn a_grid_with_seeds_refuses_an_axis_that_sets_the_seed() {
    let tmp = tempfile::tempdir().expect("tmp");
    let path = tmp.path().join("g.toml");
    std::fs::write(
        &path,
        "title = \"t\"\nout = \"o\"\nbase = \"b.toml\"\nseeds = [1, 2]\n[testset]\ndir = \"ts\"\n\
         [[rows]]\nname = \"a\"\nset = { run = { seed = 5 } }\n",
    )
    .expect("write");
    let msg = AblateConfig::load(&path)
        .expect_err("seed twice")
        .to_string();
    assert!(msg.contains("g.toml") && msg.contains("run.seed"), "{msg}");
}

// ---------------------------------------------------------------------------------------------
// Seeds and the control cell, trained

#[test]
fn a_two_seed_grid_trains_every_trained_cell_per_seed_and_a_control_on_the_pretraining_data() {
    let tmp = tempfile::tempdir().expect("tmp");
    let root = tmp.path();
    let data = root.join("train");
    common::generate(&data, 11, 3, (64, 48), "[-3.0, 0.0]");
    radiance(&root.join("radiance"));
    let pre = root.join("pretrain");
    let pre_text = train_toml(&pre, &data, 2, None);
    let pre_cfg: TrainConfig =
        hdrsynth::config::parse_toml(&pre_text, Path::new("pre.toml")).expect("pretrain config");
    hdrsynth::train::run(&pre_cfg, &TrainOptions::default()).expect("pretrain");

    // The base fine-tunes on Canon-realistic data with its own learning rate and schedule; the
    // pretraining was pure data at lr 1e-3, constant.
    let canon = SensorProfile::shipped_dir().join("canon_eos_550d.toml");
    let base = root.join("base.toml");
    let base_text = train_toml(Path::new("unused"), &data, STEPS, Some(&pre)).replace(
        "profile = \"pure\"\n[optim]\nlr = 1e-3\n",
        &format!(
            "profile = {canon:?}\nisos = [100]\n[optim]\nlr = 4e-3\n\
             [schedule]\nkind = \"cosine\"\n"
        ),
    );
    std::fs::write(&base, &base_text).expect("base");
    let cfg_path = root.join("grid.toml");
    std::fs::write(
        &cfg_path,
        format!(
            "title = \"seeds\"\nout = {:?}\nbase = {base:?}\nseeds = [1, 2]\n\
             [testset]\ndir = {:?}\nradiance = {:?}\nprofile = {canon:?}\n\
             [testset.options]\nisos = [100, 1600]\n\
             [eval]\nresamples = 200\ntile = 32\n\
             [[rows]]\nname = \"net_o\"\ntrain = false\n\
             [[rows]]\nname = \"net_s\"\n\
             [[rows]]\nname = \"control\"\nkind = \"control\"\n",
            root.join("grid"),
            root.join("testset"),
            root.join("radiance"),
        ),
    )
    .expect("grid");
    let cfg = AblateConfig::load(&cfg_path).expect("config");
    let summary = ablate::run(&cfg, &cfg_path, false).expect("grid");
    let ids: Vec<&str> = summary.cells.iter().map(|c| c.id.as_str()).collect();
    assert_eq!(
        ids,
        [
            "net_o",
            "net_s/seed1",
            "net_s/seed2",
            "control/seed1",
            "control/seed2"
        ]
    );
    let grid = root.join("grid");
    let unit = |cell: &str, seed: u64| grid.join("cells").join(cell).join(format!("seed{seed}"));

    // Each seed trained its own network: different per-set scores.
    let scores = |dir: &Path| std::fs::read_to_string(dir.join("eval/per_image.csv")).expect("csv");
    assert_ne!(scores(&unit("net_s", 1)), scores(&unit("net_s", 2)));
    // The grid's mean is the mean of the per-seed evaluations' own means, and seeds_positive
    // counts the seeds whose mean beats Net_O's (evaluated once).
    let t = csv_rows(&grid.join("table.csv"));
    for m in ["psnr_t", "psnr_l", "ssim_t", "ssim_l"] {
        let seeds = [
            summary_mean(&unit("net_s", 1), m),
            summary_mean(&unit("net_s", 2), m),
        ];
        let net_o = summary_mean(&grid.join("cells/net_o"), m);
        let r = find_row(&t, &[("row", "net_s"), ("metric", m)]);
        assert!(
            (num(r, "mean") - (seeds[0] + seeds[1]) / 2.0).abs() < 1e-9,
            "{m}"
        );
        let positive = seeds.iter().filter(|&&s| s > net_o).count();
        assert_eq!(r["seeds_positive"], positive.to_string(), "{m}");
        assert_eq!((r["n_seeds"].as_str(), r["n_scenes"].as_str()), ("2", "2"));
    }

    // The control: the pretraining run's config with the base's run/optim/schedule/init.
    let control_run = unit("control", 1).join("run");
    // (config.toml blanks run.steps, so it is read without validation.)
    let got: TrainConfig =
        hdrsynth::config::load_toml(&control_run.join("config.toml")).expect("control config");
    // As the pretraining run recorded it (its exposure rule resolved, as every run records).
    let pre_saved: TrainConfig =
        hdrsynth::config::load_toml(&pre.join("config.toml")).expect("pretraining config");
    assert_eq!(got.data, pre_saved.data, "the pretraining data");
    assert_eq!(got.model, pre_cfg.model);
    assert_eq!(got.optim.lr, 4e-3, "the base's learning rate");
    assert_eq!(got.run.seed, 1);
    assert_eq!(
        got.init.and_then(|i| i.checkpoint).as_deref(),
        Some(pre.as_path()),
        "from the pretrained checkpoint"
    );
    // And it is exactly that training: a hand-written config of that recipe, run by hand, gives
    // the same weights.
    let by_hand = root.join("by_hand");
    let hand_text = train_toml(&by_hand, &data, STEPS, Some(&pre))
        .replace("seed = 3\n", "seed = 1\n")
        .replace("lr = 1e-3\n", "lr = 4e-3\n[schedule]\nkind = \"cosine\"\n");
    let hand: TrainConfig =
        hdrsynth::config::parse_toml(&hand_text, Path::new("hand.toml")).expect("hand config");
    hdrsynth::train::run(&hand, &TrainOptions::default()).expect("by hand");
    let (a, b) = (final_weights(&control_run), final_weights(&by_hand));
    assert_eq!(a.len(), b.len());
    for (i, (x, y)) in a.iter().zip(&b).enumerate() {
        assert!(
            x.iter().zip(y).all(|(p, q)| p.to_bits() == q.to_bits()),
            "parameter {i}: the control differs from the hand-made run of its recipe"
        );
    }
}

/// Every float parameter of a run's final Network-1 checkpoint (checkpoint files hold parameter
/// ids that differ between runs, so the weights are compared, not the bytes).
fn final_weights(run: &Path) -> Vec<Vec<f32>> {
    let dir = checkpoint::resolve(run).expect("checkpoint");
    let ModelConfig::BlendUnet(cfg) = checkpoint::read_state(&dir).expect("state").model else {
        panic!("a Network-1 checkpoint expected");
    };
    let dev = Device::flex();
    let model =
        checkpoint::load_model(seeded_init(&dev, 0, || cfg.init(&dev)).expect("init"), &dir)
            .expect("load");
    struct V(Vec<Vec<f32>>);
    impl ModuleVisitor for V {
        fn visit_float<const D: usize>(&mut self, p: &Param<Tensor<D>>) {
            self.0
                .push(p.val().into_data().try_to_vec::<f32>().expect("f32"));
        }
    }
    let mut v = V(Vec::new());
    model.visit(&mut v);
    v.0
}

#[test]
fn a_control_cell_without_a_pretrained_run_is_an_error_naming_the_file() {
    let tmp = tempfile::tempdir().expect("tmp");
    let root = tmp.path();
    let grid = |base: &Path| {
        let path = root.join("grid.toml");
        std::fs::write(
            &path,
            format!(
                "title = \"t\"\nout = \"o\"\nbase = {base:?}\n[testset]\ndir = \"ts\"\n\
                 [[rows]]\nname = \"control\"\nkind = \"control\"\n"
            ),
        )
        .expect("grid");
        let cfg = AblateConfig::load(&path).expect("config");
        ablate::train_configs(&cfg, &path)
            .expect_err("no pretrained run")
            .to_string()
    };
    // No [init] checkpoint in the base: the control has nothing to continue.
    let base = root.join("base.toml");
    std::fs::write(&base, train_toml(Path::new("r"), Path::new("d"), 4, None)).expect("base");
    let msg = grid(&base);
    assert!(msg.contains("base.toml") && msg.contains("[init]"), "{msg}");
    // An [init] checkpoint whose run has no config.toml: named.
    let missing = root.join("not_a_run");
    std::fs::write(
        &base,
        train_toml(Path::new("r"), Path::new("d"), 4, Some(&missing)),
    )
    .expect("base");
    let msg = grid(&base);
    assert!(
        msg.contains("control") && msg.contains("not_a_run/config.toml"),
        "{msg}"
    );
}

/// Network-1's baselines run without a network: no run folder, no checkpoint; with noise-free
/// test frames the Mertens weights of the "noisy" pair are the reference's own weights, so that
/// cell's output is the reference (MSE 0), while the constant blend is not. A test set's own
/// `reference` overrides the grid's.
#[test]
fn baseline_cells_score_without_a_network_and_a_test_set_can_name_its_own_reference() {
    let tmp = tempfile::tempdir().expect("tmp");
    let root = tmp.path();
    radiance(&root.join("radiance"));
    let base = root.join("base.toml");
    std::fs::write(
        &base,
        train_toml(Path::new("unused"), &root.join("data"), 2, None),
    )
    .expect("base");
    let canon = SensorProfile::shipped_dir().join("canon_eos_550d.toml");
    let path = root.join("grid.toml");
    let text = format!(
        "title = \"baselines\"\nout = {:?}\nbase = {base:?}\n\
         [testset]\ndir = {:?}\nradiance = {:?}\nprofile = {canon:?}\n\
         [testset.options]\nisos = [100]\nevs = [-3.0, 0.0]\nnoise = \"none\"\n\
         [[also]]\nname = \"again\"\ndir = {:?}\nreference = \"constant\"\n\
         [eval]\nresamples = 100\nreference = \"mertens\"\n\
         [[rows]]\nname = \"constant\"\nkind = \"constant\"\n\
         [[rows]]\nname = \"mertens\"\nkind = \"mertens\"\n",
        root.join("grid"),
        root.join("testset"),
        root.join("radiance"),
        root.join("testset"),
    );
    std::fs::write(&path, &text).expect("grid");
    let cfg = AblateConfig::load(&path).expect("config");
    assert!(!cfg.cell_trains(0, None) && !cfg.cell_trains(1, None));
    ablate::run(&cfg, &path, false).expect("grid");
    for cell in ["constant", "mertens"] {
        let dir = root.join("grid/cells").join(cell);
        assert!(!dir.join("run").exists(), "{cell} trained");
        let plan = std::fs::read_to_string(dir.join("cell.toml")).expect("cell.toml");
        assert!(plan.contains(&format!("baseline = \"{cell}\"")), "{plan}");
        assert!(!plan.contains("checkpoint"), "{plan}");
    }
    let mertens = summary_mean(&root.join("grid/cells/mertens"), "psnr_t");
    let constant = summary_mean(&root.join("grid/cells/constant"), "psnr_t");
    assert!(
        mertens > 100.0 || mertens.is_infinite(),
        "Mertens {mertens}"
    );
    assert!(
        constant.is_finite() && constant < 60.0,
        "constant {constant}"
    );
    // The primary table's reference is the grid's (mertens), the `also` table's its own.
    let primary = csv_rows(&root.join("grid/table.csv"));
    let again = csv_rows(&root.join("grid/table_again.csv"));
    let diff = |t: &[BTreeMap<String, String>], row: &str| {
        find_row(t, &[("row", row), ("metric", "ssim_t")])["diff_vs_reference"].clone()
    };
    assert_eq!(diff(&primary, "mertens"), "");
    assert_ne!(diff(&primary, "constant"), "");
    assert_eq!(diff(&again, "constant"), "");
    assert_ne!(diff(&again, "mertens"), "");
    let n_pre =
        find_row(&primary, &[("row", "constant"), ("metric", "psnr_t")])["n_pretrain_seeds"]
            .clone();
    assert_eq!(n_pre, "0", "a baseline has no pretraining");
    // A baseline cannot name a checkpoint; a test set's reference must be a cell.
    for (bad, what) in [
        (
            text.replace(
                "kind = \"mertens\"\n",
                "kind = \"mertens\"\ncheckpoint = \"x\"\n",
            ),
            "baseline",
        ),
        (
            text.replace("reference = \"constant\"", "reference = \"nope\""),
            "nope",
        ),
    ] {
        std::fs::write(&path, &bad).expect("bad");
        let msg = AblateConfig::load(&path).expect_err(what).to_string();
        assert!(msg.contains(what), "{what}: {msg}");
    }
}

/// ΔE2000 and PSNR-T dark come from per_image.csv's appended columns by name; a set whose
/// PSNR-T dark is empty (too few under-exposed pixels) is left out of that metric only, and a
/// file without the columns gives those metrics no row. Expected values by hand.
#[test]
fn delta_e_and_dark_psnr_columns_are_tabled_with_missing_values_left_out() {
    let tmp = tempfile::tempdir().expect("tmp");
    let rows = "[[rows]]\nname = \"a\"\ntrain = false\n[[rows]]\nname = \"b\"\ntrain = false\n\
                [[rows]]\nname = \"old\"\ntrain = false\n";
    let cfg = grid_config(tmp.path(), "", rows);
    let header = "set,psnr_l,psnr_t,ssim_l,ssim_t,pu21_psnr,pu21_ssim,width,height,seconds,\
                  delta_e2000,psnr_t_dark,dark_fraction\n";
    for (cell, lines) in [
        (
            0,
            [
                "x_iso100,1,30,0.9,0.9,1,0.9,8,8,0,2.0,20,0.2",
                "y_iso100,1,31,0.9,0.9,1,0.9,8,8,0,3.0,,0.004",
                "z_iso100,1,32,0.9,0.9,1,0.9,8,8,0,4.0,22,0.3",
            ],
        ),
        (
            1,
            [
                "x_iso100,1,30,0.9,0.9,1,0.9,8,8,0,1.5,21,0.2",
                "y_iso100,1,31,0.9,0.9,1,0.9,8,8,0,2.5,,0.004",
                "z_iso100,1,32,0.9,0.9,1,0.9,8,8,0,3.0,25,0.3",
            ],
        ),
    ] {
        let eval = cfg.cell_dir(cell, None).join("eval");
        std::fs::create_dir_all(&eval).expect("mkdir");
        std::fs::write(
            eval.join("per_image.csv"),
            format!("{header}{}\n", lines.join("\n")),
        )
        .expect("per_image");
        std::fs::write(eval.join("summary.csv"), "metric\n").expect("summary");
    }
    write_scores(
        &cfg.cell_dir(2, None).join("eval"),
        &[("x_iso100", 30.0), ("y_iso100", 31.0), ("z_iso100", 32.0)],
    );
    ablate::write_table(&cfg).expect("table");
    let t = csv_rows(&tmp.path().join("grid/table.csv"));
    let de = find_row(&t, &[("row", "b"), ("metric", "delta_e2000")]);
    assert!((num(de, "mean") - 7.0 / 3.0).abs() < 1e-12, "{de:?}");
    assert!(
        (num(de, "diff_vs_reference") + 2.0 / 3.0).abs() < 1e-12,
        "{de:?}"
    );
    assert_eq!(de["n_scenes"], "3");
    let dark = find_row(&t, &[("row", "b"), ("metric", "psnr_t_dark")]);
    assert!((num(dark, "mean") - 23.0).abs() < 1e-12, "{dark:?}");
    assert!(
        (num(dark, "diff_vs_reference") - 2.0).abs() < 1e-12,
        "{dark:?}"
    );
    assert_eq!(dark["n_scenes"], "2");
    assert!(
        !t.iter()
            .any(|r| r["row"] == "old"
                && (r["metric"] == "delta_e2000" || r["metric"] == "psnr_t_dark")),
        "a file without the columns has no such rows"
    );
    let old_psnr = find_row(&t, &[("row", "old"), ("metric", "psnr_t")]);
    assert!((num(old_psnr, "mean") - 31.0).abs() < 1e-12);
    let md = std::fs::read_to_string(tmp.path().join("grid/table.md")).expect("md");
    assert!(md.contains("ΔE2000") && md.contains("PSNR-T dark"), "{md}");
}
