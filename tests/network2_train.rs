//! Network-2 through the shared trainer: PSNR-T on held-out generated sets rises in a short CPU
//! run; `hdrsynth infer --set` at full frame size, tiled equal to untiled; the shipped
//! training configs parse and validate.

mod common;

use burn::module::Module;
use burn::tensor::Device;
use hdrsynth::config::parse_toml;
use hdrsynth::eval::infer::{network2_frames, network2_hdr};
use hdrsynth::eval::tiling::Tiling;
use hdrsynth::models::{WuConfig, WuVariant};
use hdrsynth::train::TrainOptions;
use hdrsynth::train::config::TrainConfig;
use std::path::Path;
use std::process::Command;

fn generate(dir: &Path, seed: u64, count: usize) {
    common::generate(dir, seed, count, (96, 80), "[-2.0, 0.0, 2.0]");
}

fn validation_at(run: &Path, step: u64) -> (f64, f64) {
    (
        common::validation_at(run, step, "psnr_t"),
        common::validation_at(run, step, "psnr_l"),
    )
}

#[test]
fn a_short_run_raises_psnr_t_on_held_out_sets_and_infers_whole_sets() {
    let tmp = tempfile::tempdir().expect("tmp");
    let (train, val) = (tmp.path().join("train"), tmp.path().join("val"));
    generate(&train, 31, 6);
    generate(&val, 32, 3);
    let run = tmp.path().join("run");
    let text = format!(
        "[run]\nout = {run:?}\nseed = 4\nsteps = 120\ncheckpoint_every = 120\nlog_every = 10\n\
         [model]\nkind = \"wu\"\nbase_width = 8\nres_blocks = 2\n\
         [data]\ndataset = {train:?}\npatch = 32\nbatch_size = 4\nprofile = \"pure\"\n\
         [optim]\nlr = 2e-3\nbeta1 = 0.5\n\
         [validation]\ndataset = {val:?}\nevery = 120\nsamples = 3\npatch = 64\n"
    );
    let cfg: TrainConfig = parse_toml(&text, Path::new("net2.toml")).expect("config");
    let s = hdrsynth::train::run(&cfg, &TrainOptions::default()).expect("train");
    let (t0, l0) = validation_at(&run, 0);
    let (t1, l1) = validation_at(&run, 120);
    println!(
        "Network-2 (base 8, 2 res blocks), 120 steps: train loss {:.5} → {:.5}; held-out \
         PSNR-T {t0:.2} → {t1:.2} dB, PSNR-L {l0:.2} → {l1:.2} dB",
        s.first_loss, s.last_loss
    );
    assert!(t1 > t0 + 5.0, "PSNR-T {t0} → {t1}");
    assert!(s.last_loss < 0.5 * s.first_loss);

    // `hdrsynth infer --set` on a whole 96×80 held-out set: untiled and in 32-px tiles.
    let set = common::first_set(&val);
    let infer = |out: &Path, tile: &str| {
        let st = Command::new(env!("CARGO_BIN_EXE_hdrsynth"))
            .args(["infer", "--checkpoint"])
            .arg(&run)
            .arg("--set")
            .arg(&set)
            .arg("--out")
            .arg(out)
            .args(["--tile", tile])
            .status()
            .expect("infer");
        assert!(st.success());
        assert!(out.join("hdr_mulaw.png").is_file());
        hdrsynth::io::read_image(&out.join("hdr.exr")).expect("hdr.exr")
    };
    let whole = infer(&tmp.path().join("whole"), "384");
    let tiled = infer(&tmp.path().join("tiled"), "32");
    assert_eq!((whole.width, whole.height), (96, 80));
    let worst = common::max_abs_diff(&whole.data, &tiled.data);
    println!("infer --set: max |tiled − untiled| = {worst:e}");
    assert!(worst <= 1e-4, "tiled vs untiled: {worst}");
    // Output unit: 1 = the reference's white; the network's range reaches 1/0.25 = 4.
    assert!(whole.data.iter().all(|&v| (0.0..=4.0).contains(&v)));

    // Fine-tuning from weights trained elsewhere: export the checkpoint as SafeTensors, start a
    // run from the file; its step-0 validation is the trained model's.
    let dir = hdrsynth::train::checkpoint::resolve(&run).expect("checkpoint");
    let dev = Device::flex();
    let fresh = WuConfig {
        base_width: 8,
        res_blocks: 2,
        ..WuConfig::default()
    };
    let trained = hdrsynth::train::checkpoint::load_model(
        hdrsynth::models::seeded_init(&dev, 0, || fresh.init(&dev)).expect("init"),
        &dir,
    )
    .expect("load");
    let weights = tmp.path().join("wu.safetensors");
    hdrsynth::models::import::export_weights(&trained, &weights).expect("export");
    let run2 = tmp.path().join("from_safetensors");
    let text2 = text
        .replace(&format!("{run:?}"), &format!("{run2:?}"))
        .replace("steps = 120", "steps = 1")
        + &format!("[init]\nsafetensors = {weights:?}\n");
    let cfg2: TrainConfig = parse_toml(&text2, Path::new("net2_ft.toml")).expect("config");
    hdrsynth::train::run(&cfg2, &TrainOptions::default()).expect("fine-tune");
    assert_eq!(validation_at(&run2, 0), (t1, l1));
}

/// The Wu ResNet (tiny widths, one residual block: receptive-field radius 44 px) in tiles
/// equals the untiled network once the overlap covers the receptive field.
#[test]
fn wu_tiled_equals_untiled_when_the_overlap_covers_the_receptive_field() {
    let cfg = WuConfig {
        variant: WuVariant::Resnet,
        base_width: 4,
        res_blocks: 1,
        ..WuConfig::default()
    };
    // 3 stride-2 convs (2 + 4 + 8), one block at stride 8 (16), 3 deconvs (16 + 8 + 4), head 2.
    assert_eq!(cfg.receptive_radius(), 60);
    assert_eq!(WuConfig::default().receptive_radius(), 188);
    let dev = Device::flex();
    let model = hdrsynth::models::seeded_init(&dev, 8, || cfg.init(&dev))
        .expect("init")
        .valid();
    let tmp = tempfile::tempdir().expect("tmp");
    generate(tmp.path(), 40, 1);
    let info = hdrsynth::data::layout::detect(tmp.path()).expect("layout");
    let (frames, times) = network2_frames(&info.sets[0]).expect("frames");
    assert_eq!(times, [0.25, 1.0, 4.0]);
    let [a, b, c] = &frames;
    let run = |tile: usize, overlap: usize| {
        let t = Tiling {
            tile,
            overlap,
            multiple: 8,
        };
        network2_hdr(&model, [a, b, c], times, t, &dev).expect("infer")
    };
    let whole = run(96, 60);
    let diff = |x: &hdrsynth::io::Image| {
        whole
            .data
            .iter()
            .zip(&x.data)
            .map(|(p, q)| (p - q).abs())
            .fold(0.0f32, f32::max)
    };
    for tile in [32, 40] {
        let d = diff(&run(tile, 60));
        println!("tile {tile}, overlap 60: max diff {d:e}");
        assert!(d <= 1e-4, "tile {tile}: {d}");
    }
    let d = diff(&run(32, 8));
    println!("tile 32, overlap 8: max diff {d:e}");
    // An untrained network varies little, but any seam shows against the exact (0) result.
    assert!(d > 1e-6, "seams expected with overlap 8 < 60 ({d})");
}

#[test]
fn shipped_training_configs_parse_and_validate() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("configs");
    for name in [
        "net1_pretrain.toml",
        "net1_finetune.toml",
        "net2_pretrain.toml",
        "net2_finetune.toml",
    ] {
        let cfg = TrainConfig::load(&dir.join(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(cfg.run.steps > 0, "{name}");
        if name.contains("finetune") {
            assert!(cfg.init.is_some(), "{name} must start from a checkpoint");
            assert_ne!(
                cfg.data.realism.profile,
                std::path::Path::new("pure"),
                "{name} is the sensor-realistic stage"
            );
        }
    }
}
