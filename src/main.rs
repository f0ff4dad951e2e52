use anyhow::Result;
use clap::{Parser, Subcommand};
use std::path::PathBuf;

/// Sensor-realistic synthetic data for multi-frame HDR networks.
#[derive(Parser)]
#[command(name = "hdrsynth", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render a pure synthetic multi-exposure dataset with the procedural scene engine.
    Generate {
        /// Generation config (TOML), e.g. configs/generate.toml.
        #[arg(long)]
        config: PathBuf,
        /// Output dataset folder (resumes if it holds an interrupted run of the same config).
        #[arg(long)]
        out: PathBuf,
    },
    /// Fit a sensor profile's colour transform or noise model from real captures, or read them
    /// from DNG tags.
    Calibrate {
        #[command(subcommand)]
        command: CalibrateCommand,
    },
    /// Build or edit sensor profiles (e.g. import darktable's measured noise profiles).
    Profile {
        #[command(subcommand)]
        command: hdrsynth::cli::profile::ProfileCommand,
    },
    /// Apply a sensor profile (colour, noise, levels, response) to synthetic frames offline.
    Realism(hdrsynth::cli::realism::Args),
    /// Train Network-1 or Network-2 from a TOML config (pretrain, fine-tune, --resume).
    Train(hdrsynth::cli::train::Args),
    /// Run a trained network (any checkpoint) on one input of any size, tiled.
    Infer(hdrsynth::cli::infer::Args),
    /// Score a test set: predictions made elsewhere, or a checkpoint's network run here.
    Eval(hdrsynth::cli::eval::Args),
    /// Build a static test set from real HDR radiance through a sensor profile.
    Testset(hdrsynth::cli::testset::Args),
    /// The main job: docs/protocol.md's primary comparison on embedded defaults (Net_S against
    /// the fair pure baseline Net_R, Net_P, Net_O, the control; 3 seeds; paired tests);
    /// `--full` runs the whole protocol.
    Quickstart(hdrsynth::cli::quickstart::Args),
    /// Run an ablation grid (fine-tune per cell, evaluate, table like the paper's; resumable).
    Ablate(hdrsynth::cli::ablate::Args),
    /// Sim-to-real gap: name, fit and add the effects a profile misses, from real captures.
    Diagnose(hdrsynth::cli::diagnose::Args),
    /// Export a trained network (ONNX; cargo feature `onnx`).
    Export {
        #[command(subcommand)]
        command: hdrsynth::cli::export::ExportCommand,
    },
    /// Inspect datasets.
    Dataset {
        #[command(subcommand)]
        command: DatasetCommand,
    },
}

#[derive(Subcommand)]
enum CalibrateCommand {
    /// Colour transform T from a ColorChecker24 capture (real) vs its synthetic rendering.
    Colour(hdrsynth::cli::calibrate::colour::Args),
    /// Noise σ² = a·I + b per ISO and channel from a capture set (captures.toml).
    Noise(hdrsynth::cli::calibrate::noise::Args),
    /// Colour, levels and noise per ISO from DNG tags (ColorMatrix, NoiseProfile, levels).
    Dng(hdrsynth::cli::calibrate::dng::Args),
}

#[derive(Subcommand)]
enum DatasetCommand {
    /// Detect a folder's layout and list its sets, sizes, EVs and dynamic range.
    Info {
        dir: PathBuf,
        /// Decode every frame, mask and ground truth and check its size against its set
        /// (slow: one full decode per file); exits non-zero when a file is bad.
        #[arg(long)]
        verify: bool,
    },
    /// Blend-class maps per set, class frequencies and inverse-frequency weights (+ plot).
    Weights(hdrsynth::cli::weights::Args),
    /// Contact sheet of loader samples: pure frames, realistic frames, target.
    Preview(hdrsynth::cli::preview::Args),
}

fn main() -> Result<()> {
    hdrsynth::device::retain_freed_memory();
    let cli = Cli::parse();
    match cli.command {
        Command::Generate { config, out } => {
            let summary = hdrsynth::cli::generate::run(&config, &out, true)?;
            println!("{}", summary.report(&out));
        }
        Command::Calibrate {
            command: CalibrateCommand::Colour(args),
        } => println!("{}", hdrsynth::cli::calibrate::colour::run(&args)?),
        Command::Calibrate {
            command: CalibrateCommand::Noise(args),
        } => println!("{}", hdrsynth::cli::calibrate::noise::run(&args)?),
        Command::Calibrate {
            command: CalibrateCommand::Dng(args),
        } => println!("{}", hdrsynth::cli::calibrate::dng::run(&args)?),
        Command::Profile { command } => println!("{}", hdrsynth::cli::profile::run(&command)?),
        Command::Realism(args) => println!("{}", hdrsynth::cli::realism::run(&args)?),
        Command::Train(args) => {
            println!(
                "{}",
                hdrsynth::cli::train::report(&hdrsynth::cli::train::run(&args)?)
            )
        }
        Command::Infer(args) => println!("{}", hdrsynth::cli::infer::run(&args)?),
        Command::Eval(args) => println!("{}", hdrsynth::cli::eval::run(&args)?),
        Command::Testset(args) => println!("{}", hdrsynth::cli::testset::run(&args)?),
        Command::Quickstart(args) => println!("{}", hdrsynth::cli::quickstart::run(&args)?),
        Command::Ablate(args) => println!("{}", hdrsynth::cli::ablate::run(&args)?),
        Command::Diagnose(args) => println!("{}", hdrsynth::cli::diagnose::run(&args)?),
        Command::Export { command } => println!("{}", hdrsynth::cli::export::run(&command)?),
        Command::Dataset { command } => match command {
            DatasetCommand::Info { dir, verify } => {
                let (report, bad) = hdrsynth::cli::dataset::info_report_verified(&dir, verify)?;
                print!("{report}");
                if bad > 0 {
                    anyhow::bail!("dataset info --verify {}: {bad} bad file(s)", dir.display());
                }
            }
            DatasetCommand::Weights(args) => println!("{}", hdrsynth::cli::weights::run(&args)?),
            DatasetCommand::Preview(args) => println!("{}", hdrsynth::cli::preview::run(&args)?),
        },
    }
    Ok(())
}
