//! `hdrsynth diagnose CAPTURES [--profile P] --out DIR`: the sim-to-real gap workflow
//! (src/sensor/diagnose/, docs/diagnose.md). Writes DIR/profile.toml (the extended model),
//! DIR/report.md, DIR/report.json and plots (gap.png, radial.png, ptc.png); prints a summary.
//! `hdrsynth diagnose --brackets DIR [--profile P | --response R] --out OUT`: a bracket folder
//! as scene bursts (src/data/bracket_captures.rs), plus OUT/brackets.{md,toml} and OUT/captures.

use crate::data::bracket_captures::{self, BracketDiagnoseOptions};
use crate::data::bracket_testset::{ResponseChoice, ResponseSpec};
use crate::data::brackets::ScanOptions;
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
    #[arg(required_unless_present = "brackets", conflicts_with = "brackets")]
    pub captures: Option<PathBuf>,
    /// A bracket folder (JPEG/PNG/TIFF/DNG, as for `testset --brackets`) diagnosed as scene
    /// bursts, one per frame: response and exposure-ratio checks (docs/your_device.md).
    #[arg(long)]
    pub brackets: Option<PathBuf>,
    /// Starting model; without it the paper's base model is fitted from the captures. With
    /// --brackets: its device response linearises the frames.
    #[arg(long)]
    pub profile: Option<PathBuf>,
    /// --brackets without --profile: srgb, linear, gamma:G, debevec (default) or robertson.
    #[arg(long, conflicts_with = "profile", requires = "brackets")]
    pub response: Option<ResponseSpec>,
    /// --brackets: declared EV steps in capture order, for frames without EXIF or sidecar.
    #[arg(
        long,
        value_delimiter = ',',
        allow_hyphen_values = true,
        requires = "brackets"
    )]
    pub declared_evs: Option<Vec<f64>>,
    /// --brackets: largest gap between capture times within one set, seconds.
    #[arg(long, default_value_t = ScanOptions::default().max_gap_s)]
    pub max_gap: f64,
    /// --brackets: a frame whose exposure ratio is off the common response by more than this
    /// many stops is named and left out.
    #[arg(long, default_value_t = BracketDiagnoseOptions::default().ratio_tolerance_stops)]
    pub ratio_tolerance: f64,
    /// Output folder for profile.toml, report.md, report.json and the plots.
    #[arg(long)]
    pub out: PathBuf,
    /// Bootstrap replicates of the capture protocol per comparison.
    #[arg(long, default_value_t = DiagnoseOptions::default().replicates)]
    pub replicates: usize,
    #[arg(long, default_value_t = DiagnoseOptions::default().seed)]
    pub seed: u64,
    /// Analyse bursts larger than this on evenly spread bands of rows of about this many
    /// pixels, in the measurement and the simulation alike (0: every row; docs/diagnose.md).
    #[arg(long, default_value_t = DiagnoseOptions::default().max_pixels)]
    pub max_pixels: usize,
}

fn run_brackets(dir: &std::path::Path, args: &Args, diagnose: DiagnoseOptions) -> Result<String> {
    let t0 = Instant::now();
    let opts = BracketDiagnoseOptions {
        scan: ScanOptions {
            evs: args.declared_evs.clone(),
            max_gap_s: args.max_gap,
        },
        response: ResponseChoice::new(args.profile.as_deref(), args.response.as_ref())?,
        diagnose,
        ratio_tolerance_stops: args.ratio_tolerance,
    };
    let b = bracket_captures::diagnose_brackets(dir, &opts, &args.out)
        .with_context(|| format!("diagnosing the brackets in {}", dir.display()))?;
    let mut s = String::new();
    let _ = writeln!(s, "linearised with {}", b.linearisation);
    for n in b.notes.iter().chain(&b.ratios.notes) {
        let _ = writeln!(s, "note: {n}");
    }
    let _ = writeln!(
        s,
        "exposure ratios: {} pair(s), common exponent {:.4}",
        b.ratios.pairs.len(),
        b.ratios.exponent
    );
    for p in b.ratios.named() {
        let _ = writeln!(
            s,
            "  named: {} against {}: {:+.3} stops measured vs {:+.3} EXIF (off by {:+.3}); left out",
            p.frame.display(),
            p.reference.display(),
            p.measured_stops,
            p.exif_stops,
            p.residual_stops
        );
    }
    s.push_str(&summary(&b.diagnosis));
    for k in &b.diagnosis.skipped {
        let _ = writeln!(s, "  not tested: {k}");
    }
    let _ = write!(
        s,
        "wrote {}/{{brackets.md, brackets.toml, captures/, profile.toml, report.md, report.json, *.png}} in {:.1} s",
        args.out.display(),
        t0.elapsed().as_secs_f64()
    );
    Ok(s)
}

fn summary(d: &diagnose::Diagnosis) -> String {
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
    s
}

impl Default for Args {
    /// The command line's defaults (no capture set, no output folder).
    fn default() -> Self {
        Args {
            captures: None,
            brackets: None,
            profile: None,
            response: None,
            declared_evs: None,
            out: PathBuf::new(),
            max_gap: ScanOptions::default().max_gap_s,
            ratio_tolerance: BracketDiagnoseOptions::default().ratio_tolerance_stops,
            replicates: DiagnoseOptions::default().replicates,
            seed: DiagnoseOptions::default().seed,
            max_pixels: DiagnoseOptions::default().max_pixels,
        }
    }
}

pub fn run(args: &Args) -> Result<String> {
    let t0 = Instant::now();
    let opts = DiagnoseOptions {
        replicates: args.replicates,
        seed: args.seed,
        max_pixels: args.max_pixels,
        ..DiagnoseOptions::default()
    };
    let captures = match (&args.brackets, &args.captures) {
        (Some(dir), _) => return run_brackets(dir, args, opts),
        (None, Some(c)) => c,
        (None, None) => anyhow::bail!("give a capture set or --brackets DIR"),
    };
    // One writer per output, refused before the (long) analysis rather than after it.
    let _lock = crate::io::guard::OutputLock::acquire(&args.out, "diagnose")?;
    let set = CaptureSet::load(captures)?;
    let profile = match &args.profile {
        Some(p) => Some(SensorProfile::load(p)?),
        None => None,
    };
    let d = diagnose::diagnose(&set, profile, &opts)
        .with_context(|| format!("diagnosing {}", captures.display()))?;
    d.write(&args.out)
        .with_context(|| format!("writing the diagnosis to {}", args.out.display()))?;
    let mut s = summary(&d);
    let _ = write!(
        s,
        "wrote {}/{{profile.toml, report.md, report.json, *.png}} in {:.1} s",
        args.out.display(),
        t0.elapsed().as_secs_f64()
    );
    Ok(s)
}
