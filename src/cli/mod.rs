//! The command line: the argument parser ([`Cli`]) and one file per subcommand. The binary
//! (src/main.rs) parses and calls [`run`]; tests parse documented commands with [`Cli`].
pub mod ablate;
pub mod calibrate;
pub mod dataset;
pub mod device_loop;
pub mod diagnose;
pub mod eval;
pub mod export;
pub mod generate;
pub mod infer;
pub mod preview;
pub mod profile;
pub mod quickstart;
pub mod realism;
pub mod scan;
pub mod sweep_plot;
pub mod testset;
pub mod train;
pub mod weights;

use anyhow::Result;
use clap::{Parser, Subcommand};
use std::path::PathBuf;

/// Sensor-realistic synthetic data for multi-frame HDR networks.
#[derive(Parser)]
#[command(name = "hdrsynth", version, about)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand)]
pub enum Command {
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
        command: crate::cli::profile::ProfileCommand,
    },
    /// Apply a sensor profile (colour, noise, levels, response) to synthetic frames offline.
    Realism(crate::cli::realism::Args),
    /// Train Network-1 or Network-2 from a TOML config (pretrain, fine-tune, --resume).
    Train(crate::cli::train::Args),
    /// Run a trained network (any checkpoint) on one input of any size, tiled.
    Infer(crate::cli::infer::Args),
    /// Score a test set: predictions made elsewhere, or a checkpoint's network run here.
    Eval(crate::cli::eval::Args),
    /// Build a static test set from real HDR radiance through a sensor profile.
    Testset(crate::cli::testset::Args),
    /// The main job: docs/protocol.md's primary comparison on embedded defaults (Net_S against
    /// the fair pure baseline Net_R, Net_P, Net_O, the control; 3 seeds; paired tests);
    /// `--full` runs the whole protocol.
    Quickstart(crate::cli::quickstart::Args),
    /// Run an ablation grid (fine-tune per cell, evaluate, table like the paper's; resumable).
    Ablate(crate::cli::ablate::Args),
    /// Sim-to-real gap: name, fit and add the effects a profile misses, from real captures.
    Diagnose(crate::cli::diagnose::Args),
    /// The sim-to-real loop on a device's brackets: calibrate on some scenes, fine-tune once
    /// per measured effect, score on the others; the gain of each step, every seed.
    Loop(crate::cli::device_loop::Args),
    /// Export a trained network (ONNX; cargo feature `onnx`).
    Export {
        #[command(subcommand)]
        command: crate::cli::export::ExportCommand,
    },
    /// Plot what realism buys against how good the network is, from a sweep's table
    /// (tools/sweep.py's sweep.csv): Net_S − Net_R against Net_S − the triangle merge.
    SweepPlot(crate::cli::sweep_plot::Args),
    /// Inspect datasets.
    Dataset {
        #[command(subcommand)]
        command: DatasetCommand,
    },
}

#[derive(Subcommand)]
pub enum CalibrateCommand {
    /// Colour transform T from a ColorChecker24 capture (real) vs its synthetic rendering.
    Colour(crate::cli::calibrate::colour::Args),
    /// Noise σ² = a·I + b per ISO and channel from a capture set (captures.toml).
    Noise(crate::cli::calibrate::noise::Args),
    /// Colour, levels and noise per ISO from DNG tags (ColorMatrix, NoiseProfile, levels).
    Dng(crate::cli::calibrate::dng::Args),
    /// Response, output-domain noise and exposure rule from bracketed JPEG/PNG/TIFF frames.
    Brackets(crate::cli::calibrate::brackets::Args),
}

#[derive(Subcommand)]
pub enum DatasetCommand {
    /// Detect a folder's layout and list its sets, sizes, EVs and dynamic range.
    Info {
        dir: PathBuf,
        /// Decode every frame, mask and ground truth and check its size against its set
        /// (slow: one full decode per file); exits non-zero when a file is bad.
        #[arg(long)]
        verify: bool,
    },
    /// Blend-class maps per set, class frequencies and inverse-frequency weights (+ plot).
    Weights(crate::cli::weights::Args),
    /// Contact sheet of loader samples: pure frames, realistic frames, target.
    Preview(crate::cli::preview::Args),
}

/// The message the binary prints for a failed command: anyhow's "Error: … / Caused by:" shape,
/// less every cause whose text the lines above already hold (a library error that names its
/// cause in its own message is said once).
pub fn error_report(e: &anyhow::Error) -> String {
    let mut said = e.to_string();
    let mut out = format!("Error: {said}");
    let mut causes = Vec::new();
    for cause in e.chain().skip(1) {
        let text = cause.to_string();
        if !said.contains(&text) {
            said.push('\n');
            said.push_str(&text);
            causes.push(text);
        }
    }
    if !causes.is_empty() {
        out.push_str("\n\nCaused by:");
        for c in causes {
            out.push_str("\n    ");
            out.push_str(&c);
        }
    }
    out
}

/// Run the parsed command, printing its report.
pub fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Generate { config, out } => {
            let summary = crate::cli::generate::run(&config, &out, true)?;
            println!("{}", summary.report(&out));
        }
        Command::Calibrate {
            command: CalibrateCommand::Colour(args),
        } => println!("{}", crate::cli::calibrate::colour::run(&args)?),
        Command::Calibrate {
            command: CalibrateCommand::Noise(args),
        } => println!("{}", crate::cli::calibrate::noise::run(&args)?),
        Command::Calibrate {
            command: CalibrateCommand::Dng(args),
        } => println!("{}", crate::cli::calibrate::dng::run(&args)?),
        Command::Calibrate {
            command: CalibrateCommand::Brackets(args),
        } => println!("{}", crate::cli::calibrate::brackets::run(&args)?),
        Command::Profile { command } => println!("{}", crate::cli::profile::run(&command)?),
        Command::Realism(args) => println!("{}", crate::cli::realism::run(&args)?),
        Command::Train(args) => {
            println!(
                "{}",
                crate::cli::train::report(&crate::cli::train::run(&args)?)
            )
        }
        Command::Infer(args) => println!("{}", crate::cli::infer::run(&args)?),
        Command::Eval(args) => println!("{}", crate::cli::eval::run(&args)?),
        Command::Testset(args) => println!("{}", crate::cli::testset::run(&args)?),
        Command::Quickstart(args) => println!("{}", crate::cli::quickstart::run(&args)?),
        Command::Ablate(args) => println!("{}", crate::cli::ablate::run(&args)?),
        Command::Diagnose(args) => println!("{}", crate::cli::diagnose::run(&args)?),
        Command::Loop(args) => println!("{}", crate::cli::device_loop::run(&args)?),
        Command::Export { command } => println!("{}", crate::cli::export::run(&command)?),
        Command::SweepPlot(args) => println!("{}", crate::cli::sweep_plot::run(&args)?),
        Command::Dataset { command } => match command {
            DatasetCommand::Info { dir, verify } => {
                let (report, bad) = crate::cli::dataset::info_report_verified(&dir, verify)?;
                print!("{report}");
                if bad > 0 {
                    anyhow::bail!("dataset info --verify {}: {bad} bad file(s)", dir.display());
                }
            }
            DatasetCommand::Weights(args) => println!("{}", crate::cli::weights::run(&args)?),
            DatasetCommand::Preview(args) => println!("{}", crate::cli::preview::run(&args)?),
        },
    }
    Ok(())
}
