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
    /// Apply a sensor profile (colour, noise, levels, response) to synthetic frames offline.
    Realism(hdrsynth::cli::realism::Args),
    /// Inspect datasets.
    Dataset {
        #[command(subcommand)]
        command: DatasetCommand,
    },
}

#[derive(Subcommand)]
enum DatasetCommand {
    /// Detect a folder's layout and list its sets, sizes, EVs and dynamic range.
    Info { dir: PathBuf },
}

fn main() -> Result<()> {
    let cli = Cli::parse();
    match cli.command {
        Command::Generate { config, out } => {
            let summary = hdrsynth::cli::generate::run(&config, &out, true)?;
            println!("{}", summary.report(&out));
        }
        Command::Realism(args) => println!("{}", hdrsynth::cli::realism::run(&args)?),
        Command::Dataset {
            command: DatasetCommand::Info { dir },
        } => {
            print!("{}", hdrsynth::cli::dataset::info_report(&dir)?);
        }
    }
    Ok(())
}
