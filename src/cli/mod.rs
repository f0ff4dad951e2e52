//! Subcommands, one file each. The binary (src/main.rs) only parses and dispatches.
pub mod ablate;
pub mod calibrate;
pub mod dataset;
pub mod diagnose;
pub mod eval;
pub mod export;
pub mod generate;
pub mod infer;
pub mod preview;
pub mod profile;
pub mod quickstart;
pub mod realism;
pub mod testset;
pub mod train;
pub mod weights;

/// `--noise`: gaussian, poisson-gaussian or none.
fn parse_noise(s: &str) -> Result<crate::sensor::realism::NoiseModel, String> {
    use crate::sensor::realism::NoiseModel;
    match s {
        "gaussian" => Ok(NoiseModel::Gaussian),
        "poisson-gaussian" => Ok(NoiseModel::PoissonGaussian),
        "none" => Ok(NoiseModel::None),
        _ => Err(format!(
            "'{s}': expected gaussian, poisson-gaussian or none"
        )),
    }
}
