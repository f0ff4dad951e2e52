//! The sim-to-real loop on a device's own captures (`hdrsynth loop`, docs/your_device.md,
//! "The loop"): a bracket folder is split into calibration and test scenes (or, for a folder of
//! one scene, into two regions of the same frames, which the report says is no scene split);
//! a profile is measured from the calibration scenes alone (`calibrate brackets`); the test
//! scenes become a test set linearised and encoded through that profile's response; the
//! pretrained networks of a main job are fine-tuned once per loop step and seed, each step
//! adding one measured effect to the model; every network is scored on the test scenes and the
//! table gives the gain each step buys over the step before, paired within seed, scene and set,
//! beside Net_O, the control, the fair baseline (the device's response alone) and the `real`
//! row, fine-tuned on the calibration scenes' own frames (`real.rs`).
//!
//! The split is checked twice: here, before any work, by the captures' SHA-256 and pixels, and
//! by evaluation itself, which refuses to score a network fine-tuned with a profile calibrated
//! on a capture a test set was built from (`eval::evaluate`).

use crate::capture::linearise::ResponseChoice;
use crate::capture::output::{self, OutputCheck, OutputCheckOptions};
use crate::capture::profile::{
    BracketCalibration, BracketProfileOptions, CorrelationFit, MIN_RHO, calibrate_scanned,
    metering_rule, with_channel_correlation, with_correlation,
};
use crate::capture::scan::{self, FolderScan, Region, ScanOptions};
use crate::capture::testset::{self, BracketOptions, GtFrames, InputChoice};
use crate::error::{Error, Result};
use crate::experiments::ablate::{self, AblateConfig, Axis, AxisKind, EvalSpec, TestsetSpec};
use crate::experiments::quickstart::DYNAMIC;
use crate::io::source::{Source, overlapping};
use crate::sensor::metering::Metering;
use crate::sensor::profile::SensorProfile;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

mod handover;
mod level;
mod output_steps;
mod pictures;
mod real;
mod report;
mod split;
use report::*;
use split::{keep_split, split};

/// Simulated replicates of the device-output check of each step.
const CHECK_REPLICATES: usize = 10;
/// The row of the main job's Net_S, and where its run of seed k lies in the main job's folder.
const NET_S: &str = "net_s";
const NET_S_RUN: &str = "experiment/cells/net_s/seed{seed}/run";
/// The row fine-tuned here, as the steps are, on the main job's stock sRGB phone profile.
const GENERIC: &str = "generic";
const STOCK_PROFILE: &str = "configs/sensors/composite_phone.toml";

/// What a loop is asked for (the command's flags).
#[derive(Clone, Debug)]
pub struct LoopOptions {
    /// The device's bracket folder (one set per scene, as `testset --brackets` reads it).
    pub brackets: PathBuf,
    /// The sets that calibrate; every other set is a test scene. Empty: every set does both,
    /// each on its own region (`calibration_region`, `test_region`).
    pub calibration: Vec<String>,
    pub calibration_region: Option<Region>,
    pub test_region: Option<Region>,
    /// Declared EV steps and the largest capture gap of a set, as for `testset --brackets`.
    pub scan: ScanOptions,
    /// The test set's inputs and ground-truth frames (`testset --brackets`'s `--inputs`,
    /// `--gt-frames`).
    pub inputs: InputChoice,
    pub gt_frames: GtFrames,
    /// A finished (or at least pretrained) main job: its `pretrain/seed<k>` networks and
    /// `configs/finetune.toml` are the loop's starting points.
    pub quickstart: PathBuf,
    pub seeds: Vec<u64>,
    pub out: PathBuf,
    pub progress: bool,
}

/// One step of the loop: a row of the table, fine-tuned with `profile` (noise as `noise`).
struct Step {
    name: &'static str,
    label: String,
    profile: PathBuf,
    noise: bool,
    /// The device's exposure rule, where measured (`[data.metering]`).
    metering: Option<Metering>,
}

/// The loop's result: the calibration/test split, the tables' Markdown and the report.
pub struct LoopSummary {
    pub calibration: Vec<String>,
    pub test: Vec<String>,
    pub report: String,
}

/// The main job's pieces the loop starts from, checked before any work: its fine-tune config
/// (readable, its training set and profile present) and a complete pretrained network per
/// seed. The config's path, and its crop side.
fn check_quickstart(q: &Path, seeds: &[u64]) -> Result<(PathBuf, usize)> {
    let base = q.join("configs/finetune.toml");
    if !base.is_file() {
        return Err(Error::layout(
            q,
            "no configs/finetune.toml: run `hdrsynth quickstart --out` this folder first (its \
             pretrained networks are the loop's starting point)",
        ));
    }
    let cfg = crate::train::config::TrainConfig::load(&base).map_err(|e| {
        Error::context(
            format!("the main job's fine-tune config {}", base.display()),
            e,
        )
    })?;
    let mut needed = vec![("training set", cfg.data.dataset.clone())];
    let profile = &cfg.data.realism.profile;
    if profile != Path::new(crate::data::loader::PURE_PROFILE) {
        needed.push(("sensor profile", profile.clone()));
    }
    for (what, p) in needed {
        if !p.exists() {
            return Err(Error::layout(
                &base,
                format!(
                    "its {what} {} is missing (was the main job's folder moved or deleted?)",
                    p.display()
                ),
            ));
        }
    }
    for seed in seeds {
        let run = q.join(format!("pretrain/seed{seed}"));
        crate::train::checkpoint::resolve(&run).map_err(|e| {
            Error::context(
                format!(
                    "the main job's pretrained network for seed {seed} ({})",
                    run.display()
                ),
                e,
            )
        })?;
    }
    Ok((base, cfg.data.patch))
}

/// Run the loop (every stage resumes: a profile, test set or cell already made is kept).
pub fn run(opts: &LoopOptions) -> Result<LoopSummary> {
    if opts.seeds.is_empty() {
        return Err(Error::flag(
            "--seeds",
            "names no seed: the loop needs at least one",
        ));
    }
    // Folders by what they are, not how they are spelled: the cells record these paths.
    let resolve = crate::io::guard::resolve;
    let opts = &LoopOptions {
        brackets: resolve(&opts.brackets)?,
        quickstart: resolve(&opts.quickstart)?,
        out: resolve(&opts.out)?,
        ..opts.clone()
    };
    crate::io::guard::refuse_output_inside(&opts.brackets, &opts.out)?;
    // The folder is read once; every stage takes its sets and region from this scan.
    let folder = FolderScan::new(&opts.brackets, &opts.scan)?;
    let (cal_scan, test_scan, cal, test) = split(opts, &folder)?;
    let (base, patch) = check_quickstart(&opts.quickstart, &opts.seeds)?;
    let _lock = crate::io::guard::OutputLock::acquire(&opts.out, "loop")?;
    keep_split(opts, &cal, &test)?;
    let profiles = opts.out.join("profiles");
    std::fs::create_dir_all(&profiles).map_err(|e| Error::io(&profiles, e))?;

    let (cal_result, calibrated, mut extra) = calibrate(opts, &folder, &cal_scan, &profiles)?;
    let last_noise = [&extra.chroma, &extra.correlated]
        .into_iter()
        .flatten()
        .next()
        .unwrap_or(&calibrated)
        .clone();
    let (output, output_note, mut checked) =
        output_steps::output_steps(opts, &folder, &cal_scan, &last_noise, &profiles)?;
    let start = output.last().map_or(&last_noise, |f| &f.profile).clone();
    let (level, level_note) =
        level::level_step(opts, &folder, &cal_scan, &start, &profiles, &mut checked)?;
    extra.output = output;
    extra.level = level;
    extra.notes = output_note + &level_note;
    let fit = &cal_result.correlation;
    let testset = opts.out.join("testset");
    build_set(opts, &folder, &test_scan, &calibrated, &testset, "test")?;
    let validation = opts.out.join("validation");
    build_set(
        opts,
        &folder,
        &cal_scan,
        &calibrated,
        &validation,
        "calibration",
    )?;
    let real = real::real_row(opts, &folder, &cal_scan, &validation, patch)?;
    let steps = steps(
        &calibrated,
        &extra,
        fit,
        cal_result.channel_correlation,
        metering_rule(&cal_result.metering),
    );
    let isos: Vec<toml::Value> = cal_result
        .profile
        .noise
        .iter()
        .map(|r| r.iso.into())
        .collect();
    let mut trained_on_real: Vec<Axis> = real.iter().cloned().collect();
    if let (Some(r), Some(last)) = (trained_on_real.first(), steps.last()) {
        let base_data =
            crate::config::parse_toml::<toml::Table>(&crate::io::guard::read_text(&base)?, &base)?
                .get("data")
                .and_then(|d| d.as_table())
                .cloned()
                .unwrap_or_default();
        let mixed = real::mixed_row(r, &base_data, &step_set(last, &isos));
        trained_on_real.push(mixed);
    }
    let dynamic = dynamic_set(&opts.quickstart)?;
    let cfg = ablate_config(
        opts,
        &base,
        [&testset, &validation],
        &steps,
        &isos,
        &trained_on_real,
        dynamic,
    );
    let cfg_path = opts.out.join("loop_ablate.toml");
    crate::io::atomic::write_atomic(
        &cfg_path,
        toml::to_string(&cfg)
            .map_err(|e| Error::encode(&cfg_path, e))?
            .as_bytes(),
    )?;
    let checks = output_checks(opts, &folder, &cal_scan, &steps, checked)?;
    stage(opts, "fine-tuning and scoring every step and seed");
    ablate::run(&cfg, &cfg_path, opts.progress)?;
    let tables = ablate::write_tables(&cfg)?;
    let mut report = split_text(opts, &cal, &test);
    report.push_str(&measured_text(&cal_result, &extra));
    report.push_str(&real_text(&real));
    report.push_str(&checks_text(&steps, &checks, &opts.out)?);
    report.push_str(&steps_table(&cfg, &steps)?);
    let networks = networks(&cfg, &steps);
    report.push_str(&what_a_user_gets(&cfg, &networks)?);
    report.push_str(&dynamic_text(&cfg, &networks)?);
    report.push_str(&handover::handover_text(opts, &cfg, &cfg_path, &networks)?);
    report.push_str(&pictures_text(&cfg, &testset, &steps, &opts.out)?);
    report.push_str("\n## Every row against the fair baseline\n\n");
    report.push_str(&tables[0].markdown);
    crate::io::atomic::write_atomic(&opts.out.join("loop.md"), report.as_bytes())?;
    Ok(LoopSummary {
        calibration: cal,
        test,
        report,
    })
}

/// The sets of `scan` as a test set in `dir`, linearised through the calibration's response:
/// nothing is estimated on the scenes scored, and the frames keep the device's own codes. A
/// set already built is kept.
fn build_set(
    opts: &LoopOptions,
    folder: &FolderScan,
    scan: &ScanOptions,
    calibrated: &Path,
    dir: &Path,
    scenes: &str,
) -> Result<()> {
    if dir.join(crate::data::encoding::ENCODING_FILE).is_file() {
        return Ok(());
    }
    stage(
        opts,
        &format!("building a test set from the {scenes} scenes"),
    );
    testset::build_scanned(
        &opts.brackets,
        Some(folder.select(scan)?),
        &BracketOptions {
            scan: scan.clone(),
            response: ResponseChoice::new(Some(calibrated), None)?,
            inputs: opts.inputs.clone(),
            gt_frames: opts.gt_frames,
            ..BracketOptions::default()
        },
        dir,
    )
    .map(drop)
}

/// The grid's network rows, the least trained first (the handed-over network is chosen from
/// them; a tie keeps the first), the rows trained on real frames last.
fn networks<'a>(cfg: &'a AblateConfig, steps: &'a [Step]) -> Vec<&'a str> {
    ["net_o", NET_S, "control", GENERIC]
        .into_iter()
        .chain(steps.iter().map(|s| s.name))
        .chain([real::REAL, real::REAL_MIX])
        .filter(|n| cfg.rows.iter().any(|r| r.name == *n))
        .collect()
}

/// The profile measured on the calibration scenes (`profiles/calibrated.toml`) and, where the
/// noise's spatial correlation reaches the catalogue's minimum effect, the same with it
/// (`profiles/correlated.toml`), then with the channels' correlation (`profiles/chroma.toml`). Calibrated on every run (deterministic: a rerun writes the
/// same profile), so the fit that decides the correlated step is at hand.
fn calibrate(
    opts: &LoopOptions,
    folder: &FolderScan,
    cal_scan: &ScanOptions,
    profiles: &Path,
) -> Result<(BracketCalibration, PathBuf, Extra)> {
    let calibrated = profiles.join("calibrated.toml");
    stage(opts, "calibrating the profile on the calibration scenes");
    let mut cal = calibrate_scanned(
        &opts.brackets,
        folder.select(cal_scan)?,
        &BracketProfileOptions {
            scan: cal_scan.clone(),
            response: ResponseChoice::new(None, None)?,
            out: calibrated.clone(),
            name: Some(format!("device of {}", opts.brackets.display())),
            correlated: false,
        },
    )?;
    // Every step past the response trains with the measured noise: without it there is no loop.
    if cal.profile.noise.is_empty() {
        return Err(Error::layout(
            &opts.brackets,
            format!(
                "the calibration scenes gave no noise measurement ({}); the loop needs the \
                 device's noise",
                if cal.notes.is_empty() {
                    "no note".to_string()
                } else {
                    cal.notes.join("; ")
                }
            ),
        ));
    }
    // The steps are an ablation: those before "metering" train without the device's rule, so
    // their profiles hold none (as the loop wrote them before profiles held one); the metering
    // step gives the rule in its config.
    if cal.profile.set_metering(None).is_some() {
        cal.profile.save(&calibrated)?;
    }
    let isos: Vec<f64> = cal.profile.noise.iter().map(|r| r.iso).collect();
    let spatial = with_correlation(&cal.profile, &cal.correlation, &isos);
    let chroma = with_channel_correlation(
        spatial.as_ref().unwrap_or(&cal.profile),
        cal.channel_correlation,
    );
    let save = |p: Option<SensorProfile>, name: &str| -> Result<Option<PathBuf>> {
        p.map(|p| {
            let path = profiles.join(name);
            p.save(&path).map(|()| path)
        })
        .transpose()
    };
    let steps = Extra {
        correlated: save(spatial, "correlated.toml")?,
        chroma: save(chroma, "chroma.toml")?,
        output: Vec::new(),
        level: None,
        notes: String::new(),
    };
    Ok((cal, calibrated, steps))
}

/// The profiles of the steps that are taken only where their effect is measured.
struct Extra {
    correlated: Option<PathBuf>,
    chroma: Option<PathBuf>,
    /// The output-domain effects the device-output check names and their fits close, each on
    /// the one before (from the last noise step's profile).
    output: Vec<output_steps::Fitted>,
    /// The last step's profile with the noise level the device-output check measures.
    level: Option<level::Level>,
    /// The report's sentences on the floor and level steps (taken or not, and why).
    notes: String,
}

/// A profile's device-output check with noise (`true`) or without: checks already made are
/// kept, since steps share profiles (the exposure-rule step its predecessor's, the noise-level
/// step's fit checks its own and the last noise step's).
type Checked = Vec<(PathBuf, bool, OutputCheck)>;

/// Every step's device-output check on the calibration scenes (`known`: those made already).
fn output_checks(
    opts: &LoopOptions,
    folder: &FolderScan,
    cal_scan: &ScanOptions,
    steps: &[Step],
    mut known: Checked,
) -> Result<Vec<OutputCheck>> {
    stage(
        opts,
        "the device-output check of every step on the calibration scenes",
    );
    let mut checks = Vec::new();
    for st in steps {
        let made = known
            .iter()
            .find(|(p, noise, _)| *p == st.profile && *noise == st.noise);
        let check = match made {
            Some((_, _, c)) => c.clone(),
            None => {
                let c = output::check_scanned(
                    folder.select(cal_scan)?,
                    &SensorProfile::load(&st.profile)?,
                    &check_options(cal_scan, st.noise),
                )?;
                known.push((st.profile.clone(), st.noise, c.clone()));
                c
            }
        };
        checks.push(check);
    }
    Ok(checks)
}

/// The options of every device-output check the loop makes.
fn check_options(cal_scan: &ScanOptions, noise: bool) -> OutputCheckOptions {
    OutputCheckOptions {
        scan: cal_scan.clone(),
        replicates: CHECK_REPLICATES,
        seed: 1,
        noise,
    }
}

fn stage(opts: &LoopOptions, what: &str) {
    if opts.progress {
        eprintln!("loop: {what}");
    }
}

/// The loop's steps, each adding one measured effect to the one before: the response alone,
/// its white output noise, that noise's spatial correlation and the channels' correlation
/// where each reaches the catalogue's minimum effect, the output-domain effects (floor, JPEG)
/// and then the noise level the device-output check fits where it finds each off (and the fit
/// closes its gap), and the device's exposure rule where EXIF marks its auto-exposed frames.
fn steps(
    calibrated: &Path,
    extra: &Extra,
    fit: &CorrelationFit,
    channel_rho: f64,
    metering: Option<Metering>,
) -> Vec<Step> {
    let mut steps = vec![
        Step {
            name: "response",
            label: "device response only (the fair baseline)".into(),
            profile: calibrated.to_path_buf(),
            noise: false,
            metering: None,
        },
        Step {
            name: "noise",
            label: "+ output-domain noise (σ² = a·x + b per ISO, white)".into(),
            profile: calibrated.to_path_buf(),
            noise: true,
            metering: None,
        },
    ];
    if let Some(p) = &extra.correlated {
        steps.push(Step {
            name: "correlated",
            label: format!(
                "+ its spatial correlation (correlated_noise, lag-1 {:.3}; a, b per pixel)",
                fit.rho
            ),
            profile: p.to_path_buf(),
            noise: true,
            metering: None,
        });
    }
    if let Some(p) = &extra.chroma {
        steps.push(Step {
            name: "chroma",
            label: format!(
                "+ the channels' noise correlation (channel_correlation, {channel_rho:.3})"
            ),
            profile: p.to_path_buf(),
            noise: true,
            metering: None,
        });
    }
    for f in &extra.output {
        let about = crate::sensor::effects::entry(f.id).map_or("", |e| e.about);
        steps.push(Step {
            name: f.id,
            label: format!("+ {about} (`{}`, {})", f.id, f.fitted),
            profile: f.profile.clone(),
            noise: true,
            metering: None,
        });
    }
    if let Some(l) = &extra.level {
        steps.push(Step {
            name: "level",
            label: format!(
                "+ the noise level the frames hold against each other (a, b × {:.2}, {:.2}, \
                 {:.2}{})",
                l.scale[0],
                l.scale[1],
                l.scale[2],
                if l.floor.iter().any(Option::is_some) {
                    "; a floor added to b"
                } else {
                    ""
                }
            ),
            profile: l.profile.clone(),
            noise: true,
            metering: None,
        });
    }
    if let Some(m) = metering {
        let last = steps.last().map(|s| s.profile.clone()).unwrap_or_default();
        steps.push(Step {
            name: "metering",
            label: format!(
                "+ the device's exposure rule (mid grey {:.4}, at most {:.1} % clipped)",
                m.mid_grey,
                100.0 * m.max_clipped
            ),
            profile: last,
            noise: true,
            metering: Some(m),
        });
    }
    steps
}

/// The `set` of a fine-tuned row: its profile at the device's ISOs, without the profile's
/// colour (the device's frames carry their own), its noise unless the step has none, and its
/// exposure rule if it has one.
fn step_set(s: &Step, isos: &[toml::Value]) -> toml::Table {
    let mut data = toml::Table::new();
    data.insert("profile".into(), s.profile.display().to_string().into());
    data.insert("isos".into(), isos.to_vec().into());
    data.insert("colour".into(), false.into());
    if !s.noise {
        data.insert("noise".into(), "none".into());
    }
    if let Some(m) = &s.metering {
        let mut t = toml::Table::new();
        t.insert("mid_grey".into(), m.mid_grey.into());
        t.insert("max_clipped".into(), m.max_clipped.into());
        data.insert("metering".into(), t.into());
    }
    toml::Table::from_iter([("data".to_string(), data.into())])
}

/// No calibration, the same training as the steps: the main job's stock sRGB phone profile
/// (its response and noise at the device's ISOs, held within the profile's calibrated range),
/// where `--quickstart` holds it.
fn generic_row(opts: &LoopOptions, isos: &[toml::Value]) -> Option<Axis> {
    let stock = opts.quickstart.join(STOCK_PROFILE);
    if !stock.is_file() {
        return None;
    }
    // A profile that does not load is named by the fine-tune that reads it.
    let noise = SensorProfile::load(&stock)
        .map(|p| p.noise)
        .unwrap_or_default();
    let (lo, hi) = (
        noise.first().map_or(f64::MIN, |n| n.iso),
        noise.last().map_or(f64::MAX, |n| n.iso),
    );
    let mut held: Vec<f64> = isos
        .iter()
        .filter_map(toml::Value::as_float)
        .map(|i| i.clamp(lo, hi))
        .collect();
    held.dedup();
    let held: Vec<toml::Value> = held.into_iter().map(Into::into).collect();
    let generic = Step {
        name: GENERIC,
        label: String::new(),
        profile: stock,
        noise: true,
        metering: None,
    };
    Some(Axis {
        name: GENERIC.into(),
        label: Some(
            "generic: a stock sRGB phone profile (the main job's composite), fine-tuned here as \
             the steps are; no calibration"
                .into(),
        ),
        set: step_set(&generic, &held),
        train: true,
        checkpoint: None,
        kind: AxisKind::Finetune,
    })
}

fn ablate_config(
    opts: &LoopOptions,
    base: &Path,
    [testset, validation]: [&Path; 2],
    steps: &[Step],
    isos: &[toml::Value],
    real: &[Axis],
    dynamic: Option<TestsetSpec>,
) -> AblateConfig {
    let row = |name: &str, label: &str, set: toml::Table, train: bool, kind: AxisKind| Axis {
        name: name.into(),
        label: Some(label.into()),
        set,
        train,
        checkpoint: None,
        kind,
    };
    let mut rows = vec![
        row(
            "net_o",
            "Net_O (pretrained, no fine-tuning)",
            toml::Table::new(),
            false,
            AxisKind::Finetune,
        ),
        row(
            "control",
            "control (Net_O trained on its own data, same steps)",
            toml::Table::new(),
            true,
            AxisKind::Control,
        ),
    ];
    // No calibration: the main job's network for its stock sRGB phone (the shipped composite
    // profile), where the main job's grid has it for every seed.
    let net_s = opts.quickstart.join(NET_S_RUN);
    if opts.seeds.iter().all(|k| {
        let run = net_s
            .to_string_lossy()
            .replace(ablate::SEED_FIELD, &k.to_string());
        crate::train::checkpoint::resolve(Path::new(&run)).is_ok()
    }) {
        rows.push(Axis {
            checkpoint: Some(net_s),
            ..row(
                NET_S,
                "Net_S (the main job's network for a stock sRGB phone profile; no calibration)",
                toml::Table::new(),
                false,
                AxisKind::Finetune,
            )
        });
    }
    rows.extend(generic_row(opts, isos));
    for s in steps {
        rows.push(row(
            s.name,
            &s.label,
            step_set(s, isos),
            true,
            AxisKind::Finetune,
        ));
    }
    rows.extend(real.iter().cloned());
    rows.extend(Axis::classical_rows());
    AblateConfig {
        title: format!(
            "The sim-to-real loop on {}: each step's fine-tuned network on the test scenes",
            opts.brackets.display()
        ),
        out: opts.out.join("experiment"),
        base: base.to_path_buf(),
        seeds: opts.seeds.clone(),
        pretrained_per_seed: Some(
            opts.quickstart
                .join("pretrain/seed{seed}")
                .display()
                .to_string(),
        ),
        testset: TestsetSpec {
            label: Some("the device's test scenes".into()),
            ..test_spec(testset)
        },
        also: vec![TestsetSpec {
            name: Some("validation".into()),
            label: Some(
                "the calibration scenes (a validation set: it chooses the network the loop hands \
                 over, and tests none)"
                    .into(),
            ),
            validation: true,
            ..test_spec(validation)
        }]
        .into_iter()
        .chain(dynamic)
        .collect(),
        eval: EvalSpec {
            reference: Some(steps[0].name.into()),
            ..EvalSpec::default()
        },
        rows,
        columns: Vec::new(),
        jobs: ablate::GRID_JOBS,
    }
}

/// The main job's dynamic test set (simulated moving subjects, its stock sensor) where the
/// main job at `quickstart` declares one: every row is scored there too, so the table shows
/// whether a fine-tune on the device keeps the deghosting the pretraining taught.
fn dynamic_set(quickstart: &Path) -> Result<Option<TestsetSpec>> {
    let path = quickstart.join("configs/experiment.toml");
    if !path.is_file() {
        return Ok(None);
    }
    let main: AblateConfig =
        crate::config::parse_toml(&crate::io::guard::read_text(&path)?, &path)?;
    Ok(main
        .also
        .into_iter()
        .find(|t| t.name.as_deref() == Some(DYNAMIC))
        .filter(|t| t.dir.exists() || t.radiance.as_ref().is_some_and(|r| r.exists())))
}

/// A test set the loop built from brackets.
fn test_spec(dir: &Path) -> TestsetSpec {
    TestsetSpec {
        name: None,
        label: None,
        dir: dir.to_path_buf(),
        radiance: None,
        profile: None,
        // Unused (the test set is built from brackets); the rule pinned keeps
        // `loop_ablate.toml` as the loop wrote it before a profile could hold one.
        options: crate::data::testset::TestsetOptions {
            metering: Some(Metering::default()),
            ..Default::default()
        },
        noise_per_seed: false,
        reference: None,
        validation: false,
    }
}
