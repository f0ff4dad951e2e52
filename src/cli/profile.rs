//! `hdrsynth profile ...`: manage sensor profiles. `import-darktable` copies a camera's
//! measured noise from darktable's noise profiles (flattened CSV) into a profile;
//! `colour-from-matrix` sets T from a published XYZ→camera matrix (DNG ColorMatrix);
//! `noise-table` prints the noise σ in output codes per ISO.

use crate::sensor::darktable::{self, ImportRequest, NegativeRule, Query};
use crate::sensor::profile::{Levels, ProfileKind, SensorProfile};
use std::path::PathBuf;

#[derive(clap::Subcommand, Clone, Debug)]
pub enum ProfileCommand {
    /// Copy a camera's noise profile (a, b per ISO and channel) from darktable's noise
    /// profiles, flattened to CSV, into a sensor profile (created if missing).
    ImportDarktable(ImportArgs),
    /// Set an existing profile's colour transform T from a published XYZ→camera colour matrix
    /// (Adobe DNG ColorMatrix / dcraw adobe_coeff, D65), rows normalised to keep neutrals.
    ColourFromMatrix(MatrixArgs),
    /// Print, per ISO, the noise σ in 8-bit output codes at given fractions of white (through
    /// the profile's device response, first-order: σ_code = response'(x)·σ_x·255).
    NoiseTable(NoiseTableArgs),
}

#[derive(clap::Args, Clone, Debug)]
pub struct NoiseTableArgs {
    /// Sensor profile (TOML).
    pub profile: PathBuf,
    /// Signal levels as fractions of white (above black), comma-separated.
    #[arg(long, default_value = "0.01,0.1")]
    pub at: String,
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
    /// Kind of a new profile: `composite` when other parts (colour) will come from another
    /// device.
    #[arg(long, value_enum, default_value_t = ProfileKind::Measured)]
    pub kind: ProfileKind,
    /// Negative darktable values: `floor` replaces b < 0 by the read-noise floor (the largest
    /// positive b of the channel at a lower ISO, at least the ADC quantisation noise) and keeps
    /// a < 0; `verbatim` keeps all; `zero` writes them as 0. All are listed in provenance.
    #[arg(long, value_enum, default_value_t = NegativeRule::Floor)]
    pub negative: NegativeRule,
}

pub fn run(cmd: &ProfileCommand) -> anyhow::Result<String> {
    match cmd {
        ProfileCommand::ImportDarktable(args) => import_darktable(args),
        ProfileCommand::ColourFromMatrix(args) => colour_from_matrix(args),
        ProfileCommand::NoiseTable(args) => {
            let fractions =
                crate::sensor::colour::parse_floats(&args.at, args.at.split(',').count(), "--at")?;
            let p = SensorProfile::load(&args.profile)?;
            Ok(p.noise_table_markdown(&fractions)?)
        }
    }
}

fn colour_from_matrix(args: &MatrixArgs) -> anyhow::Result<String> {
    if args.source.trim().is_empty() {
        anyhow::bail!("--source must say where the matrix comes from");
    }
    let v = crate::sensor::colour::parse_floats(&args.matrix, 9, "--matrix")?;
    let cam_xyz: [[f64; 3]; 3] =
        std::array::from_fn(|r| std::array::from_fn(|c| v[r * 3 + c] / args.scale));
    let t = crate::sensor::colour::fit::t_from_camera_xyz(&cam_xyz)?;
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
    let req = ImportRequest {
        csv: args.csv.clone(),
        query: Query {
            maker: args.maker.clone(),
            model: args.model.clone(),
            profile_name: args.profile_name.clone(),
            set: args.set,
        },
        levels: Levels {
            black_level: args.black,
            white_level: args.white,
            bit_depth: args.bits,
        },
        levels_source: args.levels_source.clone(),
        rule: args.negative,
        out: args.out.clone(),
        name: args.name.clone(),
        kind: args.kind,
    };
    let done = darktable::import(&req)?;
    let (profile, sel) = (&done.profile, &done.selection);
    let mut report = format!(
        "{} {} ({}) from {}: {} ISO(s) {}–{}{}\n",
        if done.created { "created" } else { "updated" },
        args.out.display(),
        profile.kind,
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
    let rule = format!("{:?}", args.negative).to_lowercase();
    for c in &done.notes {
        report.push_str(&format!("negative ({rule}): {c}\n"));
    }
    Ok(report)
}
