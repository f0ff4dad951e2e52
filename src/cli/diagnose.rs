//! `hdrsynth diagnose CAPTURES [--profile P] --out DIR`: the sim-to-real gap workflow
//! (src/sensor/diagnose.rs, docs/diagnose.md). Writes DIR/profile.toml (the extended model),
//! DIR/report.md, DIR/report.json and plots (gap.png, radial.png, ptc.png); prints a summary.

use crate::sensor::captures::CaptureSet;
use crate::sensor::diagnose::{self, DiagnoseOptions};
use crate::sensor::profile::SensorProfile;
use anyhow::{Context, Result};
use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Instant;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Capture set: a directory with captures.toml (or the manifest itself).
    pub captures: PathBuf,
    /// Starting model; without it the paper's base model is fitted from the captures.
    #[arg(long)]
    pub profile: Option<PathBuf>,
    /// Output folder for profile.toml, report.md, report.json and the plots.
    #[arg(long)]
    pub out: PathBuf,
    /// Bootstrap replicates of the capture protocol per comparison.
    #[arg(long, default_value_t = 30)]
    pub replicates: usize,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

pub fn run(args: &Args) -> Result<String> {
    let t0 = Instant::now();
    // One writer per output, refused before the (long) analysis rather than after it.
    let _lock = crate::io::guard::OutputLock::acquire(&args.out, "diagnose")?;
    let set = CaptureSet::load(&args.captures)?;
    let profile = match &args.profile {
        Some(p) => Some(SensorProfile::load(p)?),
        None => None,
    };
    let opts = DiagnoseOptions {
        replicates: args.replicates,
        seed: args.seed,
        ..DiagnoseOptions::default()
    };
    let d = diagnose::diagnose(&set, profile, &opts)
        .with_context(|| format!("diagnosing {}", args.captures.display()))?;
    d.write(&args.out)
        .with_context(|| format!("writing the diagnosis to {}", args.out.display()))?;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "gap {:.2} → {:.2} (threshold {:.2}), {} step(s):",
        d.initial_gap(),
        d.final_gap(),
        d.threshold,
        d.steps.len()
    );
    for st in &d.steps {
        let _ = writeln!(
            s,
            "  + {} {{{}}}: {:.2} → {:.2} ({})",
            st.effect,
            st.params.to_string().trim().replace('\n', ", "),
            st.gap_before,
            st.gap_after,
            st.evidence
        );
    }
    for u in &d.unexplained {
        let _ = writeln!(s, "  unexplained: {u}");
    }
    let _ = write!(
        s,
        "wrote {}/{{profile.toml, report.md, report.json, *.png}} in {:.1} s",
        args.out.display(),
        t0.elapsed().as_secs_f64()
    );
    Ok(s)
}
