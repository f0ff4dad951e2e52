use super::*;
use crate::config::parse_toml;
use crate::experiments::ablate::DiffEntry;
use crate::experiments::recipe::{TARGET_PROFILE, control_row};
use crate::models::ModelConfig;
use crate::models::wu::Linearise;
use serde::Serialize;

/// The shipped DSLR profile is the 550D's with only its response replaced.
#[test]
fn the_dslr_profile_is_the_550d_with_a_gamma_response() {
    let dslr: SensorProfile =
        parse_toml(PRETRAIN_PROFILE.1, Path::new("d.toml")).expect("dslr profile parses");
    assert_eq!(dslr.response, Response::Gamma { gamma: 2.2 });
    let canon: SensorProfile = parse_toml(
        include_str!("../../../configs/sensors/canon_eos_550d.toml"),
        Path::new("c.toml"),
    )
    .expect("550D profile parses");
    assert_eq!(dslr.colour, canon.colour);
    assert_eq!(dslr.noise, canon.noise);
    assert_eq!(dslr.levels, canon.levels);
    assert_eq!(dslr.provenance.noise, canon.provenance.noise);
}

/// Serialise, parse back: the value the stage will load.
fn round_trip<T: Serialize + serde::de::DeserializeOwned>(cfg: &T) -> T {
    let text = toml::to_string(cfg).expect("serialise");
    parse_toml(&text, Path::new("written.toml")).expect(&text)
}

/// The configs the main job writes read back to the values it built and validate, for
/// both presets, and they are the protocol's (docs/protocol.md): five rows with Net_R the
/// reference, Net_R the target model without colour and noise, per-seed pretraining and
/// test noise, 24 held-out test scenes at another seed (the full run is too long for the
/// test suite; its output is in the README).
#[test]
fn the_configs_follow_the_protocol_and_read_back() {
    let root = Path::new("/r");
    let (dslr, target) = (root.join(PRETRAIN_PROFILE.0), root.join(TARGET_PROFILE.0));
    for preset in [Preset::Cpu, Preset::Gpu, Preset::Long, Preset::LongStill] {
        let s = sizes(preset);
        let gen_cfg = train_data_config(&s);
        assert_eq!(round_trip(&gen_cfg), gen_cfg);
        gen_cfg.validate().expect("valid generate config");
        let test_cfg = test_scene_config(&s);
        test_cfg.validate().expect("valid test scene config");
        assert_ne!(test_cfg.seed, gen_cfg.seed);
        assert!(test_cfg.count >= 20, "the protocol needs ≥ 20 test scenes");
        for seed in s.seeds.iter() {
            let st = Stage {
                run: root,
                seed: *seed,
                profile: &target,
                isos: &DSLR_ISOS,
                steps: s.pretrain_steps,
                lr: s.pretrain_lr,
                init: None,
            };
            let cfg = train_config(&s, s.backend, &root.join("data"), &st);
            assert_eq!(round_trip(&cfg), cfg);
            cfg.validate().expect("valid train config");
            assert_eq!(cfg.run.seed, *seed);
        }
        let src = TestSources {
            scenes: root.join("scenes"),
            dynamic: root.join("moving"),
            real_radiance: Some(root.join("hdr")),
            real_capture: Some(root.join("capture")),
        };
        let exp = experiment_config(&s, root, &root.join("ft.toml"), &src, [&dslr, &target]);
        assert_eq!(round_trip(&exp), exp);
        assert_eq!(exp.eval.reference.as_deref(), Some(REFERENCE));
        let names: Vec<&str> = exp.rows.iter().map(|r| r.name.as_str()).collect();
        assert_eq!(
            names,
            [
                "net_o",
                "control",
                "net_r",
                "net_p",
                "net_s",
                "copy",
                "triangle",
                "debevec",
                "robertson"
            ]
        );
        // The classical rows train nothing and are scored per seed (the test noise is).
        for r in &exp.rows[5..] {
            assert!(!r.train && r.set.is_empty(), "{}", r.name);
        }
        // The recipe: the merge head, inputs through the training frames' own curve, static
        // training scenes.
        let st = Stage {
            run: root,
            seed: 1,
            profile: &target,
            isos: &TARGET_ISOS,
            steps: 1,
            lr: 1e-3,
            init: None,
        };
        let cfg = train_config(&s, s.backend, root, &st);
        let ModelConfig::Wu(m) = &cfg.model else {
            panic!("Network-2");
        };
        assert_eq!(m.linearise, Linearise::Data);
        // cpu and gpu: the merge head, Wu's pooled loss, static scenes; long: the sweep's
        // `8x2hkp` (kernel head, PSNR-averaged loss, moving subjects half still, 2× the steps);
        // long-still: the same with every sample still.
        use crate::{models::wu::WuOutput, train::config::LossAverage};
        let (output, average, motion, still, steps) = match preset {
            Preset::Long => (WuOutput::Kernel, LossAverage::Psnr, 1.0, 0.5, (1600, 600)),
            Preset::LongStill => (WuOutput::Kernel, LossAverage::Psnr, 1.0, 1.0, (1600, 600)),
            Preset::Cpu => (WuOutput::Merge, LossAverage::Pixels, 0.0, 0.0, (800, 300)),
            Preset::Gpu => (
                WuOutput::Merge,
                LossAverage::Pixels,
                0.0,
                0.0,
                (20000, 4000),
            ),
        };
        assert_eq!((m.output, cfg.loss.average), (output, average));
        assert_eq!(cfg.data.static_fraction, still);
        assert_eq!(train_data_config(&s).scene.motion_scale, motion);
        assert_eq!((s.pretrain_steps, s.finetune_steps), steps);
        let net_r = &exp.rows[2].set["data"];
        assert_eq!(net_r["noise"].as_str(), Some("none"));
        assert_eq!(net_r["colour"].as_bool(), Some(false));
        assert_eq!(
            net_r["profile"].as_str(),
            exp.rows[4].set["data"]["profile"].as_str()
        );
        assert!(exp.rows[4].set["data"].get("noise").is_none());
        assert!(exp.testset.noise_per_seed);
        // The dynamic test set: the primary's options and per-seed noise, its own scenes.
        let dynamic = &exp.also[0];
        assert_eq!(dynamic.name.as_deref(), Some(reading::DYNAMIC));
        assert_eq!(
            dynamic.radiance.as_deref(),
            Some(root.join("moving").as_path())
        );
        assert_eq!(
            (&dynamic.options, dynamic.noise_per_seed, &dynamic.profile),
            (&exp.testset.options, true, &exp.testset.profile)
        );
        assert!(
            exp.pretrained_per_seed
                .as_deref()
                .is_some_and(|p| p.contains("{seed}"))
        );
        let also: Vec<_> = exp.also.iter().filter_map(|t| t.name.as_deref()).collect();
        assert_eq!(also, ["dynamic", "real_radiance", "real_capture"]);
    }
}

/// Each held-out rendering differs from the target model in one part only.
#[test]
fn each_heldout_simulator_changes_one_part_of_the_target_model() {
    let tmp = tempfile::tempdir().expect("tmp");
    let (_, _, target) = target_profile(None).expect("target");
    let specs =
        heldout_testsets(tmp.path(), Path::new("/scenes"), &target, tmp.path()).expect("heldout");
    let base = crate::data::testset::TestsetOptions {
        isos: isos(&TARGET_ISOS),
        evs: vec![-2.0, 0.0, 2.0],
        ..Default::default()
    };
    let mut changed = Vec::new();
    for t in &specs {
        let p = SensorProfile::load(t.profile.as_ref().expect("profile")).expect("load");
        let mut what = Vec::new();
        if p.response != target.response {
            what.push(format!("{:?}", p.response));
        }
        if p.colour != target.colour || p.noise != target.noise || p.levels != target.levels {
            what.push("colour/noise/levels".into());
        }
        if t.options.noise != base.noise {
            what.push(format!("{:?}", t.options.noise));
        }
        if t.options.metering != base.metering {
            what.push("metering".into());
        }
        assert_eq!(t.options.isos, base.isos);
        changed.push(what.join(" + "));
    }
    assert_eq!(
        changed,
        [
            "Gamma { gamma: 2.2 }",
            "Filmic",
            "PoissonGaussian",
            "metering"
        ]
    );
}

fn diff(mean: f64, lo: f64, hi: f64, wilcoxon: f64, tost: f64, signs: usize) -> DiffEntry {
    DiffEntry {
        mean,
        per_seed: Vec::new(),
        sign_holds: signs,
        n_seeds: 3,
        t: Some(crate::stats::PairedT {
            n: 24,
            mean,
            sd: 1.0,
            se: 0.2,
            t: mean / 0.2,
            p: 0.5,
            level: 0.95,
            ci_lower: lo,
            ci_upper: hi,
        }),
        seed_t: None,
        wilcoxon_p: Some(wilcoxon),
        margin: 0.2,
        tost_p: Some(tost),
    }
}

/// The decision rule of docs/protocol.md on hand-made cases.
#[test]
fn the_decision_follows_the_protocol() {
    let d = |x: DiffEntry| Decision::from_diff(&x, 0.05);
    assert_eq!(d(diff(0.5, 0.2, 0.8, 0.01, 0.9, 3)), Decision::Better);
    // One seed against: not "better", and not equivalent either.
    assert_eq!(d(diff(0.5, 0.2, 0.8, 0.01, 0.9, 2)), Decision::Inconclusive);
    assert_eq!(d(diff(-0.5, -0.8, -0.2, 0.01, 0.9, 3)), Decision::Worse);
    // The interval excludes 0 but Wilcoxon does not reject: not decided by the t alone.
    assert_eq!(d(diff(0.5, 0.2, 0.8, 0.2, 0.9, 3)), Decision::Inconclusive);
    assert_eq!(
        d(diff(0.02, -0.1, 0.14, 0.6, 0.01, 2)),
        Decision::Equivalent
    );
    assert_eq!(
        d(diff(0.02, -0.3, 0.34, 0.6, 0.3, 2)),
        Decision::Inconclusive
    );
    let few = DiffEntry {
        t: None,
        ..diff(3.0, 2.0, 4.0, 0.001, 0.9, 3)
    };
    assert_eq!(d(few), Decision::Inconclusive);
}

/// The reading states the interval over training runs, and that under 5 seeds it describes
/// these runs only.
#[test]
fn the_reading_gives_the_interval_over_training_runs() {
    let with_seeds = |per_seed: &[f64]| DiffEntry {
        per_seed: per_seed.iter().map(|&v| (None, v)).collect(),
        seed_t: crate::stats::paired_t(per_seed, 0.95),
        ..diff(0.5, 0.2, 0.8, 0.01, 0.9, 3)
    };
    let three = reading::describe_diff(&with_seeds(&[0.4, 0.5, 0.6]));
    // mean 0.5, sd 0.1, se 0.1/√3, t_{0.975, 2} = 4.3027: ±0.248.
    assert!(
        three.contains("over training runs [+0.25, +0.75]") && three.contains("sd 0.10"),
        "{three}"
    );
    assert!(three.contains("these runs only"), "{three}");
    let five = reading::describe_diff(&with_seeds(&[0.4, 0.5, 0.6, 0.45, 0.55]));
    assert!(
        five.contains("over training runs") && !five.contains("these runs only"),
        "{five}"
    );
}

/// `--seeds` replaces the preset's 1, 2, 3; fewer than two (no interval over training runs)
/// or a seed named twice is refused, naming the list.
#[test]
fn seeds_replace_the_presets_and_are_checked() {
    let s = |n: Option<&[u64]>| sizes_with_seeds(Preset::Long, n).map(|s| s.seeds.to_vec());
    assert_eq!(s(None).unwrap(), [1, 2, 3]);
    assert_eq!(s(Some(&[1, 2, 3, 4, 5])).unwrap(), [1, 2, 3, 4, 5]);
    for (bad, shown) in [
        (&[4][..], "--seeds 4:"),
        (&[], "--seeds :"),
        (&[1, 2, 1], "--seeds 1,2,1:"),
    ] {
        let e = s(Some(bad)).unwrap_err().to_string();
        assert!(e.contains(shown), "{e}");
    }
}

/// The main job's control row, spelled out as the pretraining's DSLR data (the grid trains the
/// pretrained runs itself, so none exists when its cells are planned), trains exactly what the
/// ablation's `control` kind reads from a finished pretrained run: the same training config.
#[test]
fn the_spelled_out_control_is_the_control_read_from_the_pretrained_run() {
    let dir = tempfile::tempdir().expect("temp dir");
    let root = dir.path();
    let (dslr, target) = (root.join(PRETRAIN_PROFILE.0), root.join(TARGET_PROFILE.0));
    let s = sizes(Preset::Cpu);
    let data = root.join("data");
    let base = root.join("finetune.toml");
    for &k in s.seeds.iter() {
        let run = root.join(format!("pretrain/seed{k}"));
        std::fs::create_dir_all(&run).expect("run folder");
        let pre = pretrain_config(Preset::Cpu, s.backend, &data, &dslr, &run, k);
        write_config(&run.join(train::RUN_CONFIG), &pre).expect("write run config");
    }
    let unused = root.join("unused");
    let init = root.join("pretrain/seed1");
    let ft = Stage {
        run: &unused,
        seed: 0,
        profile: Path::new("pure"),
        isos: &TARGET_ISOS,
        steps: s.finetune_steps,
        lr: s.finetune_lr,
        init: Some(&init),
    };
    write_config(&base, &train_config(&s, s.backend, &data, &ft)).expect("write base");
    let src = TestSources {
        scenes: root.join("scenes"),
        dynamic: root.join("moving"),
        real_radiance: None,
        real_capture: None,
    };
    let spelled = experiment_config(&s, root, &base, &src, [&dslr, &target]);
    let read = AblateConfig {
        rows: (spelled.rows.iter())
            .map(|r| {
                if r.name == "control" {
                    control_row()
                } else {
                    r.clone()
                }
            })
            .collect(),
        ..spelled.clone()
    };
    let path = root.join("experiment.toml");
    let spelled = ablate::train_configs(&spelled, &path).expect("plans");
    let read = ablate::train_configs(&read, &path).expect("plans");
    let controls = |c: &[TrainConfig]| -> Vec<TrainConfig> {
        c.iter()
            .filter(|t| t.run.out.to_string_lossy().contains("/control/"))
            .cloned()
            .collect()
    };
    assert_eq!(controls(&spelled).len(), s.seeds.len());
    assert_eq!(controls(&spelled), controls(&read));
    assert_eq!(spelled, read);
}
