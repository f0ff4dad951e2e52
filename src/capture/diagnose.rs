//! `hdrsynth diagnose --brackets DIR`: a user's own bracket folder ([`crate::capture::scan`]) as
//! scene bursts for the sim-to-real gap workflow (docs/diagnose.md, docs/your_device.md).
//!
//! Every frame of every set becomes one scene burst of one frame, with the set's name as its
//! `scene` key (captures.toml), so the workflow compares exposures only within a bracket. The
//! frames are linearised as `testset --brackets` linearises them (DNG: linear after its
//! black/white levels; otherwise the profile's device response, a declared curve, or a response
//! estimated from the brackets, [`ResponseChoice`]) and stored as DN = round(L · 65535) of a
//! noise-free sensor with white 65535 and black 0. The exposure of each burst is the frame's
//! EXIF/sidecar/declared exposure (2^stop, relative to the set's longest).
//!
//! Before the workflow runs, an **exposure-ratio check** compares, for every frame against its
//! set's middle frame, the measured ratio of linear signals (values both frames hold between 2 %
//! and 90 % of white) with the ratio from EXIF. A single power-law response p scales every log
//! ratio by p, so the check measures p as the median of measured / EXIF log ratios over all
//! pairs of the folder and names the frames whose log ratio is off that line by more than the
//! tolerance: an exposure that EXIF misreports (or a frame that moved or changed). Named frames
//! are left out of the scene bursts, so that one wrong exposure is not fitted as a response by
//! the workflow's response statistic; then the workflow runs every statistic that one-frame scene
//! bursts support (the response exponent between exposures) and lists what it skipped.

use crate::capture::linearise::{Linearise, ResponseChoice, linear_frame, resolve_linearisation};
use crate::capture::scan::{self, BracketSet, FrameKind, ScanOptions};
use crate::error::{Error, Result};
use crate::io::Image;
use crate::sensor::captures::{
    Burst, BurstKind, CaptureManifest, CaptureSet, SensorInfo, write_capture_set,
};
use crate::sensor::diagnose::{self, DiagnoseOptions, Diagnosis};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// DN of linear 1 (the frames' clipping white) in the written capture set.
pub const WHITE_DN: f64 = 65535.0;
/// Sub-folder of the output holding the capture set handed to the workflow.
pub const CAPTURES_DIR: &str = "captures";
/// The bracket side of the report.
pub const REPORT_MD: &str = "brackets.md";
pub const REPORT_TOML: &str = "brackets.toml";
/// Values used by the ratio check: both frames between these fractions of white.
const LO: f32 = 0.02;
const HI: f32 = 0.9;
/// A pair needs this many usable values to be measured.
const MIN_VALUES: usize = 64;

#[derive(Clone, Debug)]
pub struct BracketDiagnoseOptions {
    pub scan: ScanOptions,
    pub response: ResponseChoice,
    pub diagnose: DiagnoseOptions,
    /// Largest |measured − expected| log2 ratio, in stops, before a frame is named. EXIF
    /// exposure times are nominal values of a third-stop series (1/30 s for 1/32 s is 0.09
    /// stops), so the default is 0.15.
    pub ratio_tolerance_stops: f64,
    /// Also compare the frames with this profile's simulation of them in the device's output
    /// domain (`output::check`, written to `OUT/device_output.md`).
    pub device_output: Option<PathBuf>,
}

/// The device-output check's report in the output folder.
pub const DEVICE_OUTPUT_MD: &str = "device_output.md";

impl Default for BracketDiagnoseOptions {
    fn default() -> Self {
        BracketDiagnoseOptions {
            scan: ScanOptions::default(),
            response: ResponseChoice::Debevec(crate::sensor::crf::DebevecOptions::one_curve()),
            diagnose: DiagnoseOptions::default(),
            ratio_tolerance_stops: 0.15,
            device_output: None,
        }
    }
}

/// One frame against its set's reference (middle) frame.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FrameRatio {
    pub set: String,
    pub frame: PathBuf,
    pub reference: PathBuf,
    /// log2 exposure ratio frame / reference from EXIF (or sidecar, or declared EVs).
    pub exif_stops: f64,
    /// log2 of the ratio of the linear signals.
    pub measured_stops: f64,
    /// measured − exponent · exif, stops.
    pub residual_stops: f64,
    /// Usable values (both frames between 2 % and 90 % of white).
    pub values: usize,
    /// |residual| above the tolerance: the frame is named and left out of the scene bursts.
    pub named: bool,
}

/// The exposure-ratio check of a whole folder.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RatioCheck {
    /// The response exponent the ratios are compared under: the median of measured / EXIF
    /// log ratios (1 with fewer than three pairs, noted).
    pub exponent: f64,
    pub tolerance_stops: f64,
    pub pairs: Vec<FrameRatio>,
    pub notes: Vec<String>,
}

impl RatioCheck {
    pub fn named(&self) -> impl Iterator<Item = &FrameRatio> {
        self.pairs.iter().filter(|p| p.named)
    }
}

/// What `diagnose --brackets` found; the workflow's own result is in `diagnosis`.
pub struct BracketDiagnosis {
    pub diagnosis: Diagnosis,
    /// How the frames were linearised.
    pub linearisation: String,
    /// Scan, grouping and response notes.
    pub notes: Vec<String>,
    /// Per set: name, frames, how it was grouped, where its exposures came from.
    pub sets: Vec<(String, usize, String, String)>,
    pub ratios: RatioCheck,
    /// The capture set the workflow ran on (`OUT/captures`).
    pub captures: PathBuf,
    /// The device-output check, when asked for.
    pub device_output: Option<crate::capture::output::OutputCheck>,
    /// Each output-domain effect that check names, fitted in turn (each on the profile the
    /// last closing fit left), and the profile written for it where its fit closes its gap.
    pub fitted: Vec<EffectDiagnosis>,
}

/// An output-domain effect of the catalogue fitted to the folder where the device-output
/// check names it.
pub struct EffectDiagnosis {
    pub id: &'static str,
    /// The fit, or why there is none.
    pub fit: std::result::Result<crate::capture::output::EffectFit, String>,
    /// The check of the profile the fit started from.
    pub before: crate::capture::output::OutputCheck,
}

impl EffectDiagnosis {
    /// The fit closes its gap: a profile to hand on.
    pub fn closes(&self) -> bool {
        self.fit.as_ref().is_ok_and(|f| f.closes(&self.before))
    }

    /// `OUT/profile_<id>.toml`: where a closing fit's profile is written.
    pub fn file(&self) -> String {
        format!("profile_{}.toml", self.id)
    }

    fn markdown(&self) -> String {
        match &self.fit {
            Err(why) => format!("\n## `{}`\n\nNamed, not fitted: {why}.\n", self.id),
            Ok(f) => format!(
                "\n## `{}`, fitted\n\n{}{}.\n\n{}",
                self.id,
                f.text(&self.before),
                if self.closes() {
                    format!(" (the profile with it: `{}`)", self.file())
                } else {
                    "; the fit does not close its gap, no profile written".to_string()
                },
                f.check.markdown()
            ),
        }
    }
}

/// Linear frames of one set (1 = clipping white), upright, checked for one size.
fn linear_frames(set: &BracketSet, lin: &Linearise) -> Result<Vec<Image>> {
    let imgs = set
        .frames
        .iter()
        .map(|f| linear_frame(f, lin))
        .collect::<Result<Vec<Image>>>()?;
    let (w, h) = (imgs[0].width, imgs[0].height);
    for (f, img) in set.frames.iter().zip(&imgs) {
        if (img.width, img.height) != (w, h) {
            return Err(Error::layout(
                &f.path,
                format!(
                    "{}×{}, but frame {} of set '{}' is {w}×{h}",
                    img.width,
                    img.height,
                    set.frames[0].path.display(),
                    set.name
                ),
            ));
        }
    }
    Ok(imgs)
}

/// The exposure-ratio check (module doc) of `sets` with their linear frames.
pub fn ratio_check(sets: &[(&BracketSet, &[Image])], tolerance_stops: f64) -> RatioCheck {
    let mut pairs = Vec::new();
    let mut notes = Vec::new();
    for (set, imgs) in sets {
        let r = set.frames.len() / 2;
        for (j, f) in set.frames.iter().enumerate() {
            if j == r {
                continue;
            }
            let (mut sj, mut sr, mut n) = (0.0f64, 0.0f64, 0usize);
            for (&a, &b) in imgs[j].data.iter().zip(&imgs[r].data) {
                if (LO..HI).contains(&a) && (LO..HI).contains(&b) {
                    sj += f64::from(a);
                    sr += f64::from(b);
                    n += 1;
                }
            }
            if n < MIN_VALUES {
                notes.push(format!(
                    "set '{}': {} shares only {n} values between {} % and {} % of white with \
                     the reference {}; its exposure ratio is not measured",
                    set.name,
                    f.path.display(),
                    LO * 100.0,
                    HI * 100.0,
                    set.frames[r].path.display()
                ));
                continue;
            }
            pairs.push(FrameRatio {
                set: set.name.clone(),
                frame: f.path.clone(),
                reference: set.frames[r].path.clone(),
                exif_stops: f.stop - set.frames[r].stop,
                measured_stops: (sj / sr).log2(),
                residual_stops: 0.0,
                values: n,
                named: false,
            });
        }
    }
    // The response exponent every pair shares under a power law; the median, so that a few
    // misreported exposures do not move it.
    let exponent = if pairs.len() >= 3 {
        let mut slopes: Vec<f64> = pairs
            .iter()
            .map(|p| p.measured_stops / p.exif_stops)
            .collect();
        crate::stats::median(&mut slopes)
    } else {
        if !pairs.is_empty() {
            notes.push(format!(
                "only {} frame pair(s): the ratios are compared with a linear response \
                 (exponent 1), so a response error would show as an exposure error here",
                pairs.len()
            ));
        }
        1.0
    };
    for p in &mut pairs {
        p.residual_stops = p.measured_stops - exponent * p.exif_stops;
        p.named = p.residual_stops.abs() > tolerance_stops;
    }
    RatioCheck {
        exponent,
        tolerance_stops,
        pairs,
        notes,
    }
}

/// Scan `dir`, linearise, check the exposure ratios, write the scene bursts to
/// `out/captures`, run the gap workflow on them and write its report and the bracket report
/// (`brackets.md`, `brackets.toml`) to `out`.
pub fn diagnose_brackets(
    dir: &Path,
    opts: &BracketDiagnoseOptions,
    out: &Path,
) -> Result<BracketDiagnosis> {
    if !(opts.ratio_tolerance_stops.is_finite() && opts.ratio_tolerance_stops > 0.0) {
        return Err(Error::flag(
            "--ratio-tolerance",
            format!("{} stops must be positive", opts.ratio_tolerance_stops),
        ));
    }
    // The output would otherwise be scanned as a sub-folder of brackets on the next run.
    crate::io::guard::refuse_output_inside(dir, out)?;
    let scan::BracketScan { sets, mut notes } = scan::scan(dir, &opts.scan)?;
    let _lock = crate::io::guard::OutputLock::acquire(out, "diagnose --brackets")?;
    let lin = resolve_linearisation(&sets, &opts.response, Some(out), &mut notes)?;
    let estimated = matches!(
        opts.response,
        ResponseChoice::Debevec(_) | ResponseChoice::Robertson(_)
    );
    let all_dng = sets
        .iter()
        .all(|s| s.frames.iter().all(|f| f.kind == FrameKind::Dng));
    let linearisation = if all_dng {
        "linear raw (DNG black/white levels)".to_string()
    } else {
        let mut d = opts.response.describe();
        if sets
            .iter()
            .any(|s| s.frames.iter().any(|f| f.kind == FrameKind::Dng))
        {
            d.push_str("; DNG frames linear after their black/white levels");
        }
        d
    };
    if estimated && !all_dng {
        notes.push(
            "the response was estimated from these brackets with their EXIF exposures, so the \
             response check is partly circular (the estimate absorbs what the EXIF ratios imply); \
             give --profile or --response with a known curve to test a response"
                .to_string(),
        );
    }
    let linear: Vec<Vec<Image>> = sets
        .iter()
        .map(|s| linear_frames(s, &lin))
        .collect::<Result<_>>()?;
    let with_frames: Vec<(&BracketSet, &[Image])> = sets
        .iter()
        .zip(&linear)
        .map(|(s, l)| (s, l.as_slice()))
        .collect();
    let ratios = ratio_check(&with_frames, opts.ratio_tolerance_stops);

    // One scene burst per frame not named by the ratio check.
    let mut manifest = CaptureManifest::new();
    manifest.sensor = SensorInfo {
        name: Some(format!("brackets {}", dir.display())),
        white_level: Some(WHITE_DN),
        black_level: Some(0.0),
    };
    let mut frames: Vec<Vec<Image>> = Vec::new();
    for (set, imgs) in sets.iter().zip(&linear) {
        let top = set.frames.last().map_or(0.0, |f| f.stop);
        for (k, (f, img)) in set.frames.iter().zip(imgs).enumerate() {
            if ratios.named().any(|p| p.frame == f.path) {
                continue;
            }
            let name = format!("{}_{}", set.name, k + 1);
            manifest.bursts.push(Burst {
                name: name.clone(),
                kind: BurstKind::Scene,
                iso: 100.0,
                exposure_s: (f.stop - top).exp2(),
                frames: vec![format!("{name}.png")],
                scene: Some(set.name.clone()),
            });
            frames.push(vec![
                img.map(|v| (f64::from(v.clamp(0.0, 1.0)) * WHITE_DN).round() as f32),
            ]);
        }
    }
    let captures = out.join(CAPTURES_DIR);
    std::fs::create_dir_all(&captures).map_err(|e| Error::io(&captures, e))?;
    write_capture_set(&captures, &manifest, &frames)?;
    let set = CaptureSet::load(&captures)?;
    let diagnosis = diagnose::diagnose(&set, None, &opts.diagnose)?;
    let device_output = device_output_check(dir, opts)?;
    let fitted = match (&device_output, &opts.device_output) {
        (Some(c), Some(p)) => fit_output_effects(dir, p, c, opts)?,
        _ => Vec::new(),
    };
    diagnosis.write(out)?;
    let summary = BracketDiagnosis {
        diagnosis,
        linearisation,
        notes,
        sets: sets
            .iter()
            .map(|s| {
                (
                    s.name.clone(),
                    s.frames.len(),
                    s.grouping.clone(),
                    s.exposure_source.clone(),
                )
            })
            .collect(),
        ratios,
        captures,
        device_output,
        fitted,
    };
    summary.write(out)?;
    Ok(summary)
}

/// The device-output check of `opts.device_output`'s profile on the folder, when asked for.
fn device_output_check(
    dir: &Path,
    opts: &BracketDiagnoseOptions,
) -> Result<Option<crate::capture::output::OutputCheck>> {
    let Some(p) = &opts.device_output else {
        return Ok(None);
    };
    crate::capture::output::check(
        dir,
        &crate::sensor::profile::SensorProfile::load(p)?,
        &check_options(opts),
    )
    .map(Some)
}

fn check_options(opts: &BracketDiagnoseOptions) -> crate::capture::output::OutputCheckOptions {
    crate::capture::output::OutputCheckOptions {
        scan: opts.scan.clone(),
        replicates: opts.diagnose.replicates,
        seed: opts.diagnose.seed,
        noise: true,
    }
}

/// Each output-domain effect the check of `profile` names, fitted in turn on the profile the
/// last closing fit left, checked again before each.
fn fit_output_effects(
    dir: &Path,
    profile: &Path,
    first: &crate::capture::output::OutputCheck,
    opts: &BracketDiagnoseOptions,
) -> Result<Vec<EffectDiagnosis>> {
    use crate::capture::output;
    let scan = crate::capture::scan::scan(dir, &opts.scan)?;
    let mut profile = crate::sensor::profile::SensorProfile::load(profile)?;
    let mut check = first.clone();
    let mut out = Vec::new();
    for id in output::OUTPUT_EFFECTS {
        if !output::names(&check, id) {
            continue;
        }
        let fit = match output::fit_output_effect(id, &scan, &profile, &check, &check_options(opts))
        {
            Ok(f) => Ok(f),
            Err(e) => Err(output::refusal(id, e)?),
        };
        let d = EffectDiagnosis {
            id,
            fit,
            before: check.clone(),
        };
        if let (true, Ok(f)) = (d.closes(), &d.fit) {
            profile = f.profile.clone();
            check = f.check.clone();
        }
        out.push(d);
    }
    Ok(out)
}

#[derive(Serialize)]
struct Record<'a> {
    linearisation: &'a str,
    captures: &'a Path,
    notes: &'a [String],
    ratio_check: &'a RatioCheck,
}

impl BracketDiagnosis {
    /// The command's summary: linearisation, notes, the ratio check, the workflow's summary
    /// and what it did not test.
    pub fn summary(&self) -> String {
        use std::fmt::Write as _;
        let mut s = String::new();
        let _ = writeln!(s, "linearised with {}", self.linearisation);
        for n in self.notes.iter().chain(&self.ratios.notes) {
            let _ = writeln!(s, "note: {n}");
        }
        let _ = writeln!(
            s,
            "exposure ratios: {} pair(s), common exponent {:.4}",
            self.ratios.pairs.len(),
            self.ratios.exponent
        );
        for p in self.ratios.named() {
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
        s.push_str(&self.diagnosis.summary());
        for k in &self.diagnosis.skipped {
            let _ = writeln!(s, "  not tested: {k}");
        }
        if let Some(c) = &self.device_output {
            let _ = write!(s, "device-output check:\n{}", c.markdown());
        }
        for f in &self.fitted {
            s.push_str(&f.markdown());
        }
        s
    }

    pub fn report_md(&self) -> String {
        use std::fmt::Write as _;
        let mut s = String::from("# Bracket folder as scene bursts\n\n");
        let _ = writeln!(s, "Linearisation: {}.\n", self.linearisation);
        let _ = writeln!(
            s,
            "Capture set handed to the workflow: `{}` (one scene burst per frame, `scene` = the \
             set; DN = linear × {WHITE_DN}, noise-free, so only the response statistics apply; \
             report.md lists what was not tested).\n",
            self.captures.display()
        );
        s.push_str("| set | frames | grouped | exposures from |\n|---|---|---|---|\n");
        for (name, n, how, src) in &self.sets {
            let _ = writeln!(s, "| {name} | {n} | {how} | {src} |");
        }
        let r = &self.ratios;
        let _ = writeln!(
            s,
            "\n## Exposure ratios against EXIF\n\nExponent the ratios share (median of measured \
             / EXIF log ratios): {:.4}; tolerance {} stops.\n",
            r.exponent, r.tolerance_stops
        );
        s.push_str(
            "| set | frame | reference | EXIF/sidecar stops | measured stops | residual | values | named |\n\
             |---|---|---|---|---|---|---|---|\n",
        );
        for p in &r.pairs {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {:+.3} | {:+.3} | {:+.3} | {} | {} |",
                p.set,
                p.frame.display(),
                p.reference.display(),
                p.exif_stops,
                p.measured_stops,
                p.residual_stops,
                p.values,
                if p.named { "**yes**" } else { "" }
            );
        }
        if !self.notes.is_empty() || !r.notes.is_empty() {
            s.push_str("\n## Notes\n\n");
            for n in self.notes.iter().chain(&r.notes) {
                let _ = writeln!(s, "- {n}");
            }
        }
        s
    }

    /// `out/brackets.md` and `out/brackets.toml`, atomically.
    pub fn write(&self, out: &Path) -> Result<()> {
        crate::io::atomic::write_atomic(&out.join(REPORT_MD), self.report_md().as_bytes())?;
        if let Some(c) = &self.device_output {
            let fitted: String = self.fitted.iter().map(|f| f.markdown()).collect();
            crate::io::atomic::write_atomic(
                &out.join(DEVICE_OUTPUT_MD),
                format!("# The device-output check\n\n{}{fitted}", c.markdown()).as_bytes(),
            )?;
        }
        for d in self.fitted.iter().filter(|d| d.closes()) {
            if let Ok(f) = &d.fit {
                f.profile.save(&out.join(d.file()))?;
            }
        }
        let rec = Record {
            linearisation: &self.linearisation,
            captures: &self.captures,
            notes: &self.notes,
            ratio_check: &self.ratios,
        };
        let text =
            toml::to_string_pretty(&rec).map_err(|e| Error::encode(out.join(REPORT_TOML), e))?;
        crate::io::atomic::write_atomic(&out.join(REPORT_TOML), text.as_bytes())
    }
}
