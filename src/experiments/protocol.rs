//! `hdrsynth quickstart --full`: the full protocol of docs/protocol.md at CPU scale, one
//! resumable command. It runs the main job with its held-out-simulator matrix
//! (`experiments::quickstart`), then three more grids on the same test scenes, pretrainings and target
//! device:
//! - colour × fine-tuning ISO (the paper's Tables 3–4): Network-2 fine-tuned with the target's
//!   colour transform or with identity colour, at each ISO alone; scored on the primary test set
//!   and on one test set per ISO whose reference is the ISO-matched cell, so the
//!   fine-tuning-ISO × test-ISO diagonal is tested;
//! - Network-1 (the paper's Table 1): per seed, a blend-map U-Net pretrained through the DSLR
//!   model and fine-tuned four ways, beside two baselines without a network (one constant blend
//!   weight; the Mertens weights of the noisy pair), scored on EV −3/0 pairs of the test scenes
//!   at three ISOs; its learning curves (held-out blend-weight MAE against the best constant)
//!   come from the pretraining logs;
//! - scene-referred ground truth: the target's colour on the inputs only, the ground truth in
//!   scene-linear Rec. 709, Network-2 fine-tuned with scene targets with and without the colour
//!   model, beside the device-target Net_S.
//!
//! Scene seeds: training 2026, test 7 (the main job's), Network-1 validation 2027; nothing is
//! tuned on the test scenes.

use crate::data::generate::{GenerateConfig, generate};
use crate::error::{Error, Result};
use crate::experiments::ablate::{self, AblateConfig, Axis, AxisKind, EvalSpec, TestsetSpec};
use crate::experiments::presets::{self, Preset, Sizes};
use crate::experiments::quickstart::{self, Options};
use crate::experiments::recipe::{
    self, DSLR_ISOS, PRETRAIN_PROFILE, Stage, TARGET_ISOS, TRAIN_SCENE_SEED, control_row, data_set,
    generate_config, net_o_row, net_p_row, net_r_row, net_s_row, row, stage, target_profile,
    train_config, train_resumable, write, write_config,
};
use crate::models::{BlendUNetConfig, ModelConfig};
use crate::sensor::realism::TargetSpace;
use crate::train::config::{TrainConfig, ValidationConfig};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Scene seed of Network-1's validation pairs (learning curves only; used for nothing else).
const NET1_VALIDATION_SEED: u64 = 2027;

/// Network-1's sizes for a preset.
struct Net1Sizes {
    base_width: usize,
    depth: usize,
    patch: usize,
    batch: usize,
    pretrain_steps: u64,
    finetune_steps: u64,
    pretrain_lr: f64,
    finetune_lr: f64,
    validation_every: u64,
    validation_patch: usize,
}

fn net1_sizes(p: Preset) -> Net1Sizes {
    match p {
        Preset::Cpu | Preset::Long | Preset::LongStill => Net1Sizes {
            base_width: 8,
            depth: 3,
            patch: 64,
            batch: 4,
            pretrain_steps: 400,
            finetune_steps: 200,
            pretrain_lr: 2e-3,
            finetune_lr: 1e-3,
            validation_every: 50,
            validation_patch: 128,
        },
        Preset::Gpu => Net1Sizes {
            base_width: 32,
            depth: 4,
            patch: 256,
            batch: 8,
            pretrain_steps: 20000,
            finetune_steps: 4000,
            pretrain_lr: 1e-4,
            finetune_lr: 5e-5,
            validation_every: 1000,
            validation_patch: 256,
        },
    }
}

/// Network-1's training config: the main job's stage with the blend-map U-Net, its sizes and
/// validation on held-out pairs.
fn net1_config(
    s: &Sizes,
    n: &Net1Sizes,
    backend: &str,
    data: &Path,
    validation: &Path,
    st: &Stage,
) -> TrainConfig {
    let mut cfg = train_config(s, backend, data, st);
    cfg.model = ModelConfig::BlendUnet(BlendUNetConfig {
        base_width: n.base_width,
        depth: n.depth,
        batch_norm: true,
        classes: 256,
    });
    cfg.data.patch = n.patch;
    cfg.data.batch_size = n.batch;
    cfg.validation = Some(ValidationConfig {
        dataset: validation.to_path_buf(),
        generate: None,
        every: n.validation_every,
        samples: 16,
        patch: Some(n.validation_patch),
        target_sigma: 0.0,
    });
    cfg
}

/// Pure synthetic EV −3/0 pairs with linear EXRs (Network-1's frames).
fn pair_config(s: &Sizes, seed: u64, count: usize) -> GenerateConfig {
    let mut cfg = generate_config(s, seed, count, s.train_size);
    cfg.evs = vec![-3.0, 0.0];
    cfg
}

/// A test set of the main job's test scenes through the target model (noise per seed).
fn scene_testset(
    out: &Path,
    name: Option<&str>,
    target: &Path,
    isos: &[u32],
    evs: &[f32],
) -> TestsetSpec {
    TestsetSpec {
        name: name.map(Into::into),
        label: None,
        dir: out.join(format!(
            "data/testset{}",
            name.map_or(String::new(), |n| format!("_{n}"))
        )),
        radiance: Some(out.join("data/test_radiance")),
        profile: Some(target.to_path_buf()),
        options: crate::data::testset::TestsetOptions {
            isos: recipe::isos(isos),
            evs: evs.to_vec(),
            ..Default::default()
        },
        noise_per_seed: true,
        reference: None,
        validation: false,
    }
}

fn iso_name(iso: u32) -> String {
    format!("iso{iso}")
}

/// Colour × fine-tuning ISO for Network-2, with one test set per ISO.
fn colour_iso_config(s: &Sizes, out: &Path, base: &Path, target: &Path) -> AblateConfig {
    let also = TARGET_ISOS
        .iter()
        .map(|&iso| TestsetSpec {
            label: Some(format!(
                "test frames at ISO {iso} only; reference: the cell fine-tuned at ISO {iso}"
            )),
            reference: Some(format!("colour_t__{}", iso_name(iso))),
            ..scene_testset(
                out,
                Some(&format!("test_{}", iso_name(iso))),
                target,
                &[iso],
                &[-2.0, 0.0, 2.0],
            )
        })
        .collect();
    let colour = |name: &str, label: &str, on: bool| {
        row(
            name,
            label,
            data_set(target, None, &[("colour", on.into())]),
        )
    };
    AblateConfig {
        title: "Colour × fine-tuning ISO — Network-2 fine-tuned with the target's colour \
                transform or identity colour, noise drawn at one ISO"
            .into(),
        out: out.join("colour_iso"),
        base: base.to_path_buf(),
        seeds: s.seeds.to_vec(),
        pretrained_per_seed: Some(
            out.join("pretrain/seed{seed}")
                .to_string_lossy()
                .into_owned(),
        ),
        testset: scene_testset(out, None, target, &TARGET_ISOS, &[-2.0, 0.0, 2.0]),
        also,
        eval: EvalSpec {
            resamples: 2000,
            reference: Some("colour_t__iso800".into()),
            ..EvalSpec::default()
        },
        rows: vec![
            colour("colour_t", "colour: the target's T", true),
            colour(
                "colour_identity",
                "colour: identity (noise, levels, response only)",
                false,
            ),
        ],
        columns: TARGET_ISOS
            .iter()
            .map(|&iso| {
                let list = toml::Value::Array(vec![i64::from(iso).into()]);
                let data = toml::Table::from_iter([("isos".to_string(), list)]);
                Axis {
                    name: iso_name(iso),
                    label: Some(format!("fine-tuned at ISO {iso}")),
                    set: toml::Table::from_iter([("data".to_string(), data.into())]),
                    train: true,
                    checkpoint: None,
                    kind: AxisKind::Finetune,
                }
            })
            .collect(),
        jobs: ablate::GRID_JOBS,
    }
}

/// Design (a) of docs/protocol.md: the ground truth in scene-linear Rec. 709 with the target's
/// colour T on the inputs only, as a device's ISP renders, so a network has to undo T and the
/// colour model can matter. Rows: Net_O and the main job's Net_S (device-space targets) as they
/// are, and three fine-tunings with scene targets — Net_R (no colour, no noise: the fair pure
/// baseline and the reference), colour T without noise, and the full model.
fn scene_target_config(s: &Sizes, out: &Path, base: &Path, target: &Path) -> AblateConfig {
    let scene = ("target_space", toml::Value::from("scene"));
    let no_noise = ("noise", toml::Value::from("none"));
    let target_row = |name: &str, label: &str, extra: &[(&str, toml::Value)]| {
        row(name, label, data_set(target, Some(&TARGET_ISOS), extra))
    };
    let primary = scene_testset(out, None, target, &TARGET_ISOS, &[-2.0, 0.0, 2.0]);
    AblateConfig {
        title: "Scene-referred ground truth — Network-2 scored against scene-linear Rec. 709, \
                the target's colour on the inputs only"
            .into(),
        out: out.join("scene_target"),
        base: base.to_path_buf(),
        seeds: s.seeds.to_vec(),
        pretrained_per_seed: Some(
            out.join("pretrain/seed{seed}")
                .to_string_lossy()
                .into_owned(),
        ),
        testset: TestsetSpec {
            dir: out.join("data/testset_scene_target"),
            options: crate::data::testset::TestsetOptions {
                ground_truth: TargetSpace::Scene,
                ..primary.options.clone()
            },
            ..primary
        },
        also: Vec::new(),
        eval: EvalSpec {
            resamples: 2000,
            reference: Some("net_r_scene".into()),
            ..EvalSpec::default()
        },
        rows: vec![
            net_o_row(),
            target_row(
                "net_s_device",
                "Net_S with device-space targets (the main job's recipe)",
                &[],
            ),
            target_row(
                "net_r_scene",
                "Net_R, scene targets (target response, levels, exposure rule; no colour, no \
                 noise)",
                &[no_noise.clone(), ("colour", false.into()), scene.clone()],
            ),
            target_row(
                "colour_scene",
                "colour T, scene targets, no noise",
                &[no_noise, scene.clone()],
            ),
            target_row(
                "net_s_scene",
                "Net_S, scene targets (full target model)",
                &[scene],
            ),
        ],
        columns: Vec::new(),
        jobs: ablate::GRID_JOBS,
    }
}

/// Network-1's grid: four fine-tunings of the per-seed pretraining and two baselines, the
/// constant the reference.
fn network1_config(s: &Sizes, out: &Path, base: &Path, target: &Path) -> AblateConfig {
    let baseline = |name: &str, label: &str, kind: AxisKind| Axis {
        train: false,
        kind,
        ..row(name, label, toml::Table::new())
    };
    AblateConfig {
        title: "Network-1 — blend maps for the target device: Net_O, control, Net_R, Net_P, \
                Net_S against a constant blend weight and the Mertens weights of the noisy pair"
            .into(),
        out: out.join("network1"),
        base: base.to_path_buf(),
        seeds: s.seeds.to_vec(),
        pretrained_per_seed: Some(
            out.join("network1_pretrain/seed{seed}")
                .to_string_lossy()
                .into_owned(),
        ),
        testset: TestsetSpec {
            dir: out.join("data/testset_pairs"),
            ..scene_testset(out, None, target, &TARGET_ISOS, &[-3.0, 0.0])
        },
        also: Vec::new(),
        eval: EvalSpec {
            resamples: 2000,
            reference: Some("constant".into()),
            ..EvalSpec::default()
        },
        rows: vec![
            net_o_row(),
            control_row(),
            net_r_row(target),
            net_p_row(),
            net_s_row(target),
            baseline(
                "constant",
                "constant blend weight 0.5 (no network)",
                AxisKind::Constant,
            ),
            baseline(
                "mertens",
                "Mertens weights of the noisy pair (no network)",
                AxisKind::Mertens,
            ),
        ],
        columns: Vec::new(),
        jobs: ablate::GRID_JOBS,
    }
}

/// A run's validation lines: step, the network's blend-weight MAE, the best constant's and the
/// noisy pair's Mertens weights'.
struct CurvePoint {
    step: u64,
    mae: f64,
    constant: f64,
    mertens: Option<f64>,
}

fn learning_curve(run: &Path) -> Result<Vec<CurvePoint>> {
    let path = run.join(crate::train::LOG_FILE);
    let text = crate::io::guard::read_text(&path)?;
    let mut curve = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let v: serde_json::Value = serde_json::from_str(line)
            .map_err(|e| Error::layout(&path, format!("line {}: {e}", i + 1)))?;
        let (Some(step), Some(val)) = (v["step"].as_u64(), v.get("validation")) else {
            continue;
        };
        if let (Some(mae), Some(constant)) =
            (val["weight_mae"].as_f64(), val["weight_mae_const"].as_f64())
        {
            curve.push(CurvePoint {
                step,
                mae,
                constant,
                mertens: val["weight_mae_mertens"].as_f64(),
            });
        }
    }
    Ok(curve)
}

/// The learning-curve table of the runs `runs` (label, folder): MAE per validation step and
/// the final MAE over the constant's.
fn curves_table(runs: &[(String, PathBuf)]) -> Result<String> {
    let mut out = String::new();
    let curves: Vec<(&String, Vec<CurvePoint>)> = runs
        .iter()
        .map(|(l, r)| Ok((l, learning_curve(r)?)))
        .collect::<Result<_>>()?;
    let steps: Vec<u64> = curves
        .first()
        .map(|(_, c)| c.iter().map(|p| p.step).collect())
        .unwrap_or_default();
    let _ = write!(out, "| run | best constant | Mertens of the noisy pair |");
    for st in &steps {
        let _ = write!(out, " {st} |");
    }
    let _ = write!(out, " final / constant |\n|---|---|---|");
    for _ in 0..=steps.len() {
        out.push_str("---|");
    }
    out.push('\n');
    for (label, c) in curves {
        let constant = c.first().map_or(f64::NAN, |p| p.constant);
        let mertens = c
            .first()
            .and_then(|p| p.mertens)
            .map_or("–".into(), |m| format!("{m:.4}"));
        let _ = write!(out, "| {label} | {constant:.4} | {mertens} |");
        for st in &steps {
            match c.iter().find(|p| p.step == *st) {
                Some(p) => {
                    let _ = write!(out, " {:.4} |", p.mae);
                }
                None => out.push_str(" – |"),
            }
        }
        let ratio = c.last().map_or(f64::NAN, |p| p.mae / p.constant);
        let _ = writeln!(out, " {ratio:.3} |");
    }
    Ok(out)
}

/// What the protocol's grids share: sizes, backend, folders and the two profiles.
struct Setup<'a> {
    s: Sizes,
    n1: Net1Sizes,
    backend: &'a str,
    out: &'a Path,
    configs: PathBuf,
    pre_profile: PathBuf,
    target: PathBuf,
    progress: bool,
}

/// Run the full protocol into `opts.out` (the main job's folder: its data, pretrainings and
/// test scenes are shared). Returns the report, also written to OUT/protocol.md.
pub fn run(opts: &Options) -> Result<String> {
    let began = Instant::now();
    // Absolute, as the main job's configs name it: the test sets they share record their
    // sources by path, and a relative one would read as another recipe.
    let opts = &Options {
        out: crate::io::guard::resolve(&opts.out)?,
        ..opts.clone()
    };
    let main = quickstart::run(&Options {
        heldout: true,
        ..opts.clone()
    })?;
    let s = presets::sizes_with_seeds(opts.preset, opts.seeds.as_deref())?;
    let backend = opts.backend.as_deref().unwrap_or(s.backend);
    let out = &opts.out;
    let _lock = crate::io::guard::OutputLock::acquire(&out.join("protocol"), "protocol")?;
    let configs = out.join("configs");
    let sensors = configs.join("sensors");
    let x = Setup {
        n1: net1_sizes(opts.preset),
        backend,
        out,
        pre_profile: sensors.join(PRETRAIN_PROFILE.0),
        target: sensors.join(target_profile(opts.target.as_deref())?.0),
        configs,
        progress: opts.progress,
        s,
    };
    let mut report = format!("# The full protocol (docs/protocol.md)\n\n## Main job\n\n{main}\n");

    stage(x.progress, began, "colour × fine-tuning ISO (Network-2)");
    colour_iso_grid(&x, &mut report)?;
    stage(
        x.progress,
        began,
        "Network-1: data, per-seed pretraining, grid",
    );
    network1_grid(&x, &mut report)?;
    stage(
        x.progress,
        began,
        "scene-referred ground truth, colour on the inputs only (Network-2)",
    );
    scene_grid(&x, &mut report)?;
    let _ = write!(
        report,
        "\nTotal {:.1} s with the main job (backend {backend}).\n",
        began.elapsed().as_secs_f64()
    );
    write(&out.join("protocol.md"), &report)?;
    Ok(report)
}

/// Writes a grid's ablation config to `configs/FILE`, loads it back (validated as a user's file
/// would be), runs it (resumable) and appends its report under `heading`.
fn run_grid(
    x: &Setup,
    file: &str,
    cfg: &AblateConfig,
    what: &str,
    heading: &str,
    report: &mut String,
) -> Result<AblateConfig> {
    let path = x.configs.join(file);
    write_config(&path, cfg)?;
    let grid = AblateConfig::load(&path)?;
    let summary = ablate::run(&grid, &path, x.progress).map_err(|e| Error::context(what, e))?;
    let _ = write!(
        report,
        "\n## {heading}\n\n{}\n",
        ablate::report(&grid, &summary)
    );
    Ok(grid)
}

/// The colour × fine-tuning ISO grid and its ISO diagonal.
fn colour_iso_grid(x: &Setup, report: &mut String) -> Result<()> {
    let colour = run_grid(
        x,
        "colour_iso.toml",
        &colour_iso_config(&x.s, x.out, &x.configs.join("finetune.toml"), &x.target),
        "the colour × ISO grid",
        "Colour × fine-tuning ISO (Network-2)",
        report,
    )?;
    let tables = ablate::write_tables(&colour)?;
    let _ = writeln!(
        report,
        "\n### ISO diagonal (PSNR-T on each test ISO, mean over seeds; Δ to the ISO-matched \
         cell of the same colour row is in each test set's table)\n"
    );
    let _ = writeln!(
        report,
        "| test ISO | {} |\n|---|{}",
        TARGET_ISOS
            .iter()
            .map(|i| format!("fine-tuned at ISO {i} (colour T)"))
            .collect::<Vec<_>>()
            .join(" | "),
        "---|".repeat(TARGET_ISOS.len())
    );
    for &test_iso in &TARGET_ISOS {
        let name = format!("test_{}", iso_name(test_iso));
        let Some(t) = tables.iter().find(|t| t.testset.as_deref() == Some(&name)) else {
            continue;
        };
        let cells: Vec<String> = TARGET_ISOS
            .iter()
            .map(|&ft| {
                t.entries
                    .iter()
                    .find(|e| {
                        e.row == "colour_t"
                            && e.column.as_deref() == Some(&iso_name(ft))
                            && e.metric == "psnr_t"
                    })
                    .map_or("–".into(), |e| match &e.diff {
                        Some(d) => format!("{:.2} (Δ {:+.2})", e.mean, d.mean),
                        None => format!("**{:.2}**", e.mean),
                    })
            })
            .collect();
        let _ = writeln!(report, "| {test_iso} | {} |", cells.join(" | "));
    }
    Ok(())
}

/// Network-1: its pair data, per-seed pretraining, the grid and the learning curves.
fn network1_grid(x: &Setup, report: &mut String) -> Result<()> {
    let (s, n1, out, configs) = (&x.s, &x.n1, x.out, &x.configs);
    let pairs = out.join("data/train_pairs");
    let pairs_val = out.join("data/validation_pairs");
    let gen_train = configs.join("train_pairs.toml");
    let gen_val = configs.join("validation_pairs.toml");
    write_config(&gen_train, &pair_config(s, TRAIN_SCENE_SEED, s.train_sets))?;
    write_config(&gen_val, &pair_config(s, NET1_VALIDATION_SEED, 16))?;
    generate(&GenerateConfig::load(&gen_train)?, &pairs, x.progress)?;
    generate(&GenerateConfig::load(&gen_val)?, &pairs_val, x.progress)?;
    let mut curve_runs = Vec::new();
    for &k in s.seeds.iter() {
        let run = out.join(format!("network1_pretrain/seed{k}"));
        let path = configs.join(format!("network1_pretrain_seed{k}.toml"));
        let st = Stage {
            run: &run,
            seed: k,
            profile: &x.pre_profile,
            isos: &DSLR_ISOS,
            steps: n1.pretrain_steps,
            lr: n1.pretrain_lr,
            init: None,
        };
        write_config(
            &path,
            &net1_config(s, n1, x.backend, &pairs, &pairs_val, &st),
        )?;
        train_resumable(&path, x.progress).map_err(|e| {
            Error::context(format!("Network-1 pretraining ({})", path.display()), e)
        })?;
        curve_runs.push((format!("Net_O pretraining, seed {k}"), run));
    }
    let base1 = configs.join("network1_finetune.toml");
    let unused = out.join("unused");
    write_config(
        &base1,
        &net1_config(
            s,
            n1,
            x.backend,
            &pairs,
            &pairs_val,
            &Stage {
                run: &unused,
                seed: 0,
                profile: Path::new("pure"),
                isos: &TARGET_ISOS,
                steps: n1.finetune_steps,
                lr: n1.finetune_lr,
                init: Some(&out.join("network1_pretrain/seed1")),
            },
        ),
    )?;
    let net1 = run_grid(
        x,
        "network1.toml",
        &network1_config(s, out, &base1, &x.target),
        "the Network-1 grid",
        "Network-1",
        report,
    )?;
    for &k in s.seeds.iter() {
        let cell = net1.out.join(format!("cells/net_s/seed{k}/run"));
        curve_runs.push((format!("Net_S fine-tuning, seed {k}"), cell));
    }
    let _ = write!(
        report,
        "\n### Network-1 learning curves (held-out blend-weight MAE on {} validation pairs of \
         scene seed {NET1_VALIDATION_SEED}, clean targets, per-pixel; the best constant is the \
         median target weight of the same pairs)\n\n{}",
        16,
        curves_table(&curve_runs)?
    );
    Ok(())
}

/// The scene-referred ground-truth grid (Network-2).
fn scene_grid(x: &Setup, report: &mut String) -> Result<()> {
    run_grid(
        x,
        "scene_target.toml",
        &scene_target_config(&x.s, x.out, &x.configs.join("finetune.toml"), &x.target),
        "the scene-referred grid",
        "Ground truth in scene-linear Rec. 709, the target's colour on the inputs only \
         (Network-2)",
        report,
    )?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The grids the full protocol writes parse back as valid ablation configs and follow
    /// docs/protocol.md: three seeds with per-seed pretraining, one test set per ISO whose
    /// reference is the ISO-matched cell, Network-1's two baselines with the constant as the
    /// reference, and Network-1 pretrained on EV −3/0 pairs with validation on other scenes.
    #[test]
    fn the_grids_follow_the_protocol_and_parse_back() {
        let out = Path::new("/o");
        let target = out.join("target.toml");
        let s = presets::sizes(Preset::Cpu);
        let parse = |cfg: &AblateConfig| {
            let text = toml::to_string(cfg).expect("serialise");
            AblateConfig::parse(&text, Path::new("grid.toml")).expect(&text)
        };
        let colour = parse(&colour_iso_config(
            &s,
            out,
            Path::new("/o/base.toml"),
            &target,
        ));
        assert_eq!(colour.seeds, [1, 2, 3]);
        assert!(colour.pretrained_per_seed.is_some());
        assert_eq!(colour.cells().len(), 6);
        for (t, iso) in colour.also.iter().zip(TARGET_ISOS) {
            assert_eq!(t.options.isos, [f64::from(iso)]);
            assert_eq!(
                t.reference.as_deref(),
                Some(format!("colour_t__iso{iso}").as_str())
            );
            assert!(t.noise_per_seed);
        }
        let net1 = parse(&network1_config(&s, out, Path::new("/o/b1.toml"), &target));
        let names: Vec<&str> = net1.rows.iter().map(|r| r.name.as_str()).collect();
        assert_eq!(
            names,
            [
                "net_o", "control", "net_r", "net_p", "net_s", "constant", "mertens"
            ]
        );
        assert_eq!(net1.eval.reference.as_deref(), Some("constant"));
        assert_eq!(net1.testset.options.evs, [-3.0, 0.0]);
        assert_ne!(net1.testset.dir, colour.testset.dir);
        let n = net1_sizes(Preset::Cpu);
        let st = Stage {
            run: out,
            seed: 1,
            profile: &target,
            isos: &DSLR_ISOS,
            steps: n.pretrain_steps,
            lr: n.pretrain_lr,
            init: None,
        };
        let cfg = net1_config(&s, &n, "flex", out, &out.join("val"), &st);
        cfg.validate().expect("valid Network-1 config");
        assert!(matches!(cfg.model, ModelConfig::BlendUnet(_)));
        assert_eq!(
            cfg.data.target_frames,
            crate::data::loader::TargetFrames::Clean
        );
        assert_ne!(NET1_VALIDATION_SEED, recipe::TEST_SCENE_SEED);
        assert_ne!(NET1_VALIDATION_SEED, TRAIN_SCENE_SEED);
        assert_eq!(pair_config(&s, 1, 2).evs, [-3.0, 0.0]);
        let scene = parse(&scene_target_config(
            &s,
            out,
            Path::new("/o/base.toml"),
            &target,
        ));
        assert_eq!(scene.testset.options.ground_truth, TargetSpace::Scene);
        assert_ne!(scene.testset.dir, colour.testset.dir);
        assert_eq!(scene.eval.reference.as_deref(), Some("net_r_scene"));
        let space = |name: &str| {
            let r = scene.rows.iter().find(|r| r.name == name).expect(name);
            r.set
                .get("data")
                .and_then(|d| d.get("target_space"))
                .cloned()
        };
        assert_eq!(space("net_s_device"), None);
        for name in ["net_r_scene", "colour_scene", "net_s_scene"] {
            assert_eq!(space(name), Some("scene".into()), "{name}");
        }
    }
}
