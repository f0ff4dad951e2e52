//! `hdrsynth sweep-plot`: the realism-against-quality plot of a sweep's table.

use clap::Parser;
use std::path::PathBuf;

#[derive(Parser)]
pub struct Args {
    /// The sweep's table (sweep.csv).
    #[arg(long)]
    pub sweep: PathBuf,
    /// The PNG to write.
    #[arg(long)]
    pub out: PathBuf,
}

pub fn run(args: &Args) -> anyhow::Result<String> {
    crate::experiments::sweep::write_realism_plot(&args.sweep, &args.out)?;
    Ok(format!("wrote {}", args.out.display()))
}
