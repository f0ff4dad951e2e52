//! A device's realism on one rendered image: the sensor profile's colour transform T, its
//! noise σ² = a·I + b at one ISO, its levels and its response, as the training loader applies
//! them online.
//!
//!     cargo run --release --example realism_one_image -- IN.exr OUT.png \
//!         [PROFILE.toml] [ISO] [SEED]
//!
//! IN is a linear image (EXR/HDR; 1.0 = the frame's clipping point) or a display-referred PNG,
//! as `hdrsynth realism` takes them. The profile defaults to the shipped composite phone, the
//! ISO to 800, the seed to 0 (the same seed gives the same noise).
use anyhow::{Context, Result, bail};
use hdrsynth::io::{BitDepth, read_image, write_ldr};
use hdrsynth::sensor::profile::SensorProfile;
use hdrsynth::sensor::realism::{NoiseModel, Realism, RealismOptions};
use std::path::PathBuf;

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (input, output) = match &args[..] {
        [i, o, ..] => (PathBuf::from(i), PathBuf::from(o)),
        _ => bail!("usage: realism_one_image IN OUT.png [PROFILE.toml] [ISO] [SEED]"),
    };
    let profile_path = args
        .get(2)
        .map(PathBuf::from)
        .unwrap_or_else(|| SensorProfile::shipped_dir().join("composite_phone.toml"));
    let iso: f64 = args
        .get(3)
        .map_or(Ok(800.0), |s| s.parse())
        .context("ISO")?;
    let seed: u64 = args.get(4).map_or(Ok(0), |s| s.parse()).context("SEED")?;

    let profile = SensorProfile::load(&profile_path)?;
    let opts = RealismOptions {
        iso,
        exposure: 1.0,
        noise: NoiseModel::Gaussian,
        colour: true,
        output_bits: 8,
    };
    let realism = Realism::new(&profile, &opts)?;
    let image = read_image(&input)?;
    let device_frame = realism.apply(&image, seed);
    write_ldr(&output, &device_frame, BitDepth::Eight)?;
    println!(
        "{} → {} through '{}' at ISO {iso}",
        input.display(),
        output.display(),
        profile.name
    );
    Ok(())
}
