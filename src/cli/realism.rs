//! `hdrsynth realism --profile P --iso N --in FILE|DIR --out DIR`: apply a sensor profile to
//! pure synthetic frames offline. For a dataset folder, the static and dynamic frames of every
//! set are processed (masks and ground truth are not frames); for any other folder, every image
//! under it. Outputs mirror the input's relative paths as PNG. Each file's noise seed derives
//! from `--seed` and its relative path, so reruns are bit-identical.

use crate::data::layout;
use crate::io::{BitDepth, read_image, write_ldr};
use crate::rng::hash;
use crate::sensor::profile::SensorProfile;
use crate::sensor::realism::{NoiseModel, Realism, RealismOptions};
use anyhow::{Context, Result, bail};
use indicatif::{ProgressBar, ProgressStyle};
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Sensor profile (TOML), e.g. configs/sensors/canon_eos_550d.toml.
    #[arg(long)]
    pub profile: PathBuf,
    /// ISO whose noise to simulate (within the profile's calibrated range).
    #[arg(long)]
    pub iso: f64,
    /// A synthetic frame, or a folder (a dataset in a known layout, or any folder of images).
    #[arg(long = "in")]
    pub input: PathBuf,
    #[arg(long)]
    pub out: PathBuf,
    /// Multiplier on the linearised signal (1: the source's clipping point at white level).
    #[arg(long, default_value_t = 1.0)]
    pub exposure: f64,
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// gaussian (the paper's N(0, aI+b)), poisson-gaussian (exact), none.
    #[arg(long, value_enum, default_value = "gaussian")]
    pub noise: NoiseModel,
    /// Skip the colour transform (colour ablation).
    #[arg(long)]
    pub no_colour: bool,
    /// Output PNG bits: 8 or 16.
    #[arg(long, default_value_t = 8)]
    pub bits: u32,
}

/// (input file, path relative to the input root) of every frame to process.
fn inputs(root: &Path) -> Result<Vec<(PathBuf, PathBuf)>> {
    if root.is_file() {
        let name = root.file_name().map(PathBuf::from).unwrap_or_default();
        return Ok(vec![(root.to_path_buf(), name)]);
    }
    if !root.is_dir() {
        bail!("{}: no such file or folder", root.display());
    }
    let files = match layout::detect(root) {
        Ok(info) => info
            .sets
            .iter()
            .flat_map(|s| s.static_frames.iter().chain(&s.dynamic_frames).cloned())
            .collect(),
        // Symlinked folders are followed once, so a symlink loop cannot recurse forever.
        Err(_) => crate::io::guard::images_under(root)?,
    };
    if files.is_empty() {
        bail!("{}: no images found", root.display());
    }
    Ok(files
        .into_iter()
        .map(|f| {
            let rel = f
                .strip_prefix(root)
                .map(Path::to_path_buf)
                // Never an absolute path: joined to the output, it would write outside it.
                .unwrap_or_else(|_| f.file_name().map(PathBuf::from).unwrap_or_default());
            (f, rel)
        })
        .collect())
}

/// Seed of one file: the run's seed mixed with its relative path.
pub fn file_seed(seed: u64, rel: &Path) -> u64 {
    let bytes = rel.to_string_lossy();
    let words: Vec<u64> = bytes
        .as_bytes()
        .chunks(8)
        .map(|c| c.iter().fold(0u64, |h, &b| h << 8 | b as u64))
        .collect();
    hash(seed, &words)
}

pub fn run(args: &Args) -> Result<String> {
    let profile = SensorProfile::load(&args.profile)?;
    let depth = BitDepth::from_bits(args.bits).context("--bits must be 8 or 16")?;
    let opts = RealismOptions {
        iso: args.iso,
        exposure: args.exposure,
        noise: args.noise,
        colour: !args.no_colour,
        output_bits: args.bits,
    };
    let op = Realism::new(&profile, &opts)
        .with_context(|| format!("profile {}", args.profile.display()))?;
    // Never write into the input (it would overwrite frames, or re-read its own output on a
    // rerun); one writer per output; the output appears only when every frame is done.
    crate::io::guard::refuse_output_inside(&args.input, &args.out)?;
    let files = inputs(&args.input)?;
    let lock = crate::io::guard::OutputLock::acquire(&args.out, "realism")?;
    let staged = lock.stage(false)?;
    let bar = ProgressBar::new(files.len() as u64);
    bar.set_style(
        ProgressStyle::with_template("{spinner} [{elapsed_precise}] {bar:40} {pos}/{len} frames")
            .expect("static template"),
    );
    let start = Instant::now();
    let mut mpix = 0.0;
    let mut out = crate::io::Image::new(0, 0);
    for (path, rel) in &files {
        let img = read_image(path)?;
        op.apply_into(&img, file_seed(args.seed, rel), &mut out);
        let dest = staged.path().join(rel).with_extension("png");
        write_ldr(&dest, &out, depth)?;
        mpix += img.pixel_count() as f64 / 1e6;
        bar.inc(1);
    }
    bar.finish_and_clear();
    staged.commit()?;
    let secs = start.elapsed().as_secs_f64();
    Ok(format!(
        "{} frames → {} (profile '{}' ({}), ISO {}, noise {:?}, colour {}), {:.1} s, {:.1} Mpix/s incl. I/O",
        files.len(),
        args.out.display(),
        profile.name,
        profile.kind,
        args.iso,
        args.noise,
        if args.no_colour { "off" } else { "on" },
        secs,
        mpix / secs.max(1e-9)
    ))
}
