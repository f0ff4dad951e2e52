//! `hdrsynth profile ...`: manage sensor profiles. `import-darktable` copies a camera's
//! measured noise from darktable's noise profiles (flattened CSV) into a profile;
//! `colour-from-matrix` sets T from a published XYZ→camera matrix (DNG ColorMatrix);
//! `noise-table` prints the noise σ in output codes per ISO.

use crate::sensor::colour::{calibrate, parse_floats};
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
        ProfileCommand::ImportDarktable(args) => {
            let req = args.request();
            Ok(darktable::import(&req)?.report(&req))
        }
        ProfileCommand::ColourFromMatrix(args) => {
            let t =
                calibrate::colour_from_matrix(&args.matrix, args.scale, &args.source, &args.out)?;
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
        ProfileCommand::NoiseTable(args) => {
            let fractions = parse_floats(&args.at, args.at.split(',').count(), "--at")?;
            let p = SensorProfile::load(&args.profile)?;
            Ok(p.noise_table_markdown(&fractions)?)
        }
    }
}

impl ImportArgs {
    fn request(&self) -> ImportRequest {
        ImportRequest {
            csv: self.csv.clone(),
            query: Query {
                maker: self.maker.clone(),
                model: self.model.clone(),
                profile_name: self.profile_name.clone(),
                set: self.set,
            },
            levels: Levels {
                black_level: self.black,
                white_level: self.white,
                bit_depth: self.bits,
            },
            levels_source: self.levels_source.clone(),
            rule: self.negative,
            out: self.out.clone(),
            name: self.name.clone(),
            kind: self.kind,
        }
    }
}
