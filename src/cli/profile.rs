//! `hdrsynth profile ...`: manage sensor profiles. `import-darktable` copies a camera's
//! measured noise from darktable's noise profiles (flattened CSV) into a profile;
//! `colour-from-matrix` sets T from a published XYZ→camera matrix (DNG ColorMatrix).

use crate::sensor::darktable::{self, Query};
use crate::sensor::noise::new_measured_profile;
use crate::sensor::profile::{Levels, SensorProfile};
use anyhow::Context as _;
use std::path::PathBuf;

#[derive(clap::Subcommand, Clone, Debug)]
pub enum ProfileCommand {
    /// Copy a camera's noise profile (a, b per ISO and channel) from darktable's noise
    /// profiles, flattened to CSV, into a sensor profile (created if missing).
    ImportDarktable(ImportArgs),
    /// Set an existing profile's colour transform T from a published XYZ→camera colour matrix
    /// (Adobe DNG ColorMatrix / dcraw adobe_coeff, D65), rows normalised to keep neutrals.
    ColourFromMatrix(MatrixArgs),
}

#[derive(clap::Args, Clone, Debug)]
pub struct MatrixArgs {
    /// Nine numbers, row-major XYZ → camera RGB, as published (e.g. "6461,-1164,-857,...").
    #[arg(long, allow_hyphen_values = true)]
    pub matrix: String,
    /// Divide the published numbers by this (dcraw's table and DNG tags use 10000).
    #[arg(long, default_value_t = 10000.0)]
    pub scale: f64,
    /// Where the matrix comes from (stored as provenance.colour).
    #[arg(long)]
    pub source: String,
    /// The profile to update.
    #[arg(long)]
    pub out: PathBuf,
}

#[derive(clap::Args, Clone, Debug)]
pub struct ImportArgs {
    /// darktable noise profiles as CSV (maker,model,iso,a_R,a_G,a_B,b_R,b_G,b_B,profile_name).
    #[arg(long)]
    pub csv: PathBuf,
    /// Camera maker, case-insensitive exact match (e.g. "Canon").
    #[arg(long)]
    pub maker: String,
    /// Camera model, case-insensitive exact match (e.g. "EOS 550D").
    #[arg(long)]
    pub model: String,
    /// Profile name without its " iso N" suffix (or a full name), where a camera has several.
    #[arg(long)]
    pub profile_name: Option<String>,
    /// Where ISOs repeat: take the K-th row at each ISO in CSV order (1-based).
    #[arg(long)]
    pub set: Option<usize>,
    /// Black level in DN.
    #[arg(long)]
    pub black: f64,
    /// White level in DN.
    #[arg(long)]
    pub white: f64,
    /// Bits per raw sample.
    #[arg(long)]
    pub bits: u32,
    /// Where the levels come from (stored as provenance.levels).
    #[arg(long)]
    pub levels_source: String,
    /// Sensor profile to write: an existing one gets noise, levels and their provenance
    /// replaced; a new one is created (kind measured, no colour, default responses).
    #[arg(long)]
    pub out: PathBuf,
    /// Name of a new profile (default "MAKER MODEL").
    #[arg(long)]
    pub name: Option<String>,
    /// Write negative darktable values as 0 instead of verbatim (both are listed in provenance).
    #[arg(long)]
    pub clamp_negative: bool,
}

pub fn run(cmd: &ProfileCommand) -> anyhow::Result<String> {
    match cmd {
        ProfileCommand::ImportDarktable(args) => import_darktable(args),
        ProfileCommand::ColourFromMatrix(args) => colour_from_matrix(args),
    }
}

fn colour_from_matrix(args: &MatrixArgs) -> anyhow::Result<String> {
    if args.source.trim().is_empty() {
        anyhow::bail!("--source must say where the matrix comes from");
    }
    let v = crate::sensor::colour::parse_floats(&args.matrix, 9, "--matrix")?;
    let cam_xyz: [[f64; 3]; 3] =
        std::array::from_fn(|r| std::array::from_fn(|c| v[r * 3 + c] / args.scale));
    let t = crate::sensor::colour::t_from_camera_xyz(&cam_xyz)?;
    let mut p = SensorProfile::load(&args.out)?;
    p.colour = Some(crate::sensor::profile::Colour {
        matrix: t,
        root_polynomial: None,
        use_root_polynomial: false,
    });
    p.provenance.colour = format!(
        "{}; XYZ→camera matrix [{}]/{} converted by `hdrsynth profile colour-from-matrix`: \
         T = rownorm(M · sRGB→XYZ(D65)), rows scaled to sum 1 (dcraw's cam_rgb normalisation)",
        args.source.trim(),
        args.matrix,
        args.scale
    );
    p.save(&args.out)?;
    let mut report = format!(
        "updated {} (colour and provenance.colour)\nT (real = T · synthetic):\n",
        args.out.display()
    );
    for row in &t {
        report.push_str(&format!(
            "  [{:>9.5}, {:>9.5}, {:>9.5}]\n",
            row[0], row[1], row[2]
        ));
    }
    Ok(report)
}

fn import_darktable(args: &ImportArgs) -> anyhow::Result<String> {
    if args.levels_source.trim().is_empty() {
        anyhow::bail!("--levels-source must say where the black/white levels come from");
    }
    let rows = darktable::read_csv(&args.csv)?;
    let q = Query {
        maker: args.maker.clone(),
        model: args.model.clone(),
        profile_name: args.profile_name.clone(),
        set: args.set,
    };
    let sel = darktable::select(&rows, &q, &args.csv)?;
    let (noise, negative) = darktable::to_noise(&sel, args.clamp_negative);
    let noise_source = darktable::provenance(&q, &sel, &args.csv, &negative, args.clamp_negative);
    let levels = Levels {
        black_level: args.black,
        white_level: args.white,
        bit_depth: args.bits,
    };
    let existed = args.out.exists();
    let profile = if existed {
        let mut p = SensorProfile::load(&args.out).with_context(|| {
            format!(
                "{} exists but is not a valid sensor profile; not overwriting it",
                args.out.display()
            )
        })?;
        p.noise = noise;
        p.provenance.noise = noise_source;
        p.levels = levels;
        p.provenance.levels = args.levels_source.clone();
        p
    } else {
        let name = args
            .name
            .clone()
            .unwrap_or_else(|| format!("{} {}", sel.rows[0].maker, sel.rows[0].model));
        new_measured_profile(&name, levels, &args.levels_source, noise, &noise_source)
    };
    profile.save(&args.out)?;

    let mut report = format!(
        "{} {} from {}: {} ISO(s) {}–{}{}\n",
        if existed { "updated" } else { "created" },
        args.out.display(),
        args.csv.display(),
        profile.noise.len(),
        profile.noise.first().map_or(0.0, |n| n.iso),
        profile.noise.last().map_or(0.0, |n| n.iso),
        if sel.sets > 1 {
            format!(" (set {} of {})", sel.set, sel.sets)
        } else {
            String::new()
        }
    );
    report.push_str(&format!(
        "{:>7} {:>12} {:>12} {:>12} {:>12} {:>12} {:>12}\n",
        "ISO", "a_R", "a_G", "a_B", "b_R", "b_G", "b_B"
    ));
    for n in &profile.noise {
        report.push_str(&format!(
            "{:>7} {:>12.4e} {:>12.4e} {:>12.4e} {:>12.4e} {:>12.4e} {:>12.4e}\n",
            n.iso, n.a[0], n.a[1], n.a[2], n.b[0], n.b[1], n.b[2]
        ));
    }
    let how = if args.clamp_negative {
        "clamped to 0"
    } else {
        "negative, kept verbatim"
    };
    for c in &negative {
        report.push_str(&format!("{how}: {c}\n"));
    }
    Ok(report)
}
