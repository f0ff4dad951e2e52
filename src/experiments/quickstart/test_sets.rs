//! The main job's test sets beside the held-out ones: the generated test scenes, the real
//! radiance and real capture where present, and the noise ceiling on the primary test set.

use super::*;

/// The generated test scenes' linear radiance (`hdr_gt.exr` of each set), copied into one
/// folder, as `testset` reads a folder of maps.
pub(super) fn test_scenes(opts: &Options, s: &Sizes) -> Result<PathBuf> {
    let scenes = opts.out.join("data/test_scenes");
    generate(&test_scene_config(s), &scenes, opts.progress)?;
    let dir = opts.out.join("data/test_radiance");
    std::fs::create_dir_all(&dir)
        .map_err(|e| Error::context(format!("creating {}", dir.display()), e))?;
    let entries = std::fs::read_dir(&scenes)
        .map_err(|e| Error::context(format!("reading {}", scenes.display()), e))?;
    for e in entries {
        let set = e
            .map_err(|e| Error::context(format!("reading {}", scenes.display()), e))?
            .path();
        let gt = set.join("hdr_gt.exr");
        if gt.is_file() {
            let name = set
                .file_name()
                .unwrap_or_default()
                .to_string_lossy()
                .into_owned();
            let to = dir.join(format!("{name}.exr"));
            if !to.is_file() {
                let tmp = dir.join(format!(".{name}.exr.tmp"));
                std::fs::copy(&gt, &tmp).map_err(|e| {
                    Error::context(format!("copying {} to {}", gt.display(), tmp.display()), e)
                })?;
                std::fs::rename(&tmp, &to)
                    .map_err(|e| Error::context(format!("renaming {}", tmp.display()), e))?;
            }
        }
    }
    Ok(dir)
}

/// The dynamic test scenes: the scene engine at a seed of their own with moving subjects (its
/// default motion), the dynamic range of the static ones, and the linear frames `testset`
/// renders each frame from at its own time.
pub(super) fn dynamic_scenes(opts: &Options, s: &Sizes) -> Result<PathBuf> {
    let mut cfg = generate_config(s, TEST_DYNAMIC_SCENE_SEED, s.dynamic_scenes, s.test_size);
    cfg.scene.min_dynamic_range = TEST_MIN_DYNAMIC_RANGE;
    cfg.write_linear = true;
    let dir = opts.out.join("data/test_scenes_dynamic");
    generate(&cfg, &dir, opts.progress)?;
    Ok(dir)
}

/// A flag's folder, else the shared data's default when it exists. Returns the folder or why
/// there is none.
pub(super) fn optional_source(
    flag: Option<&PathBuf>,
    name: &str,
    default: &str,
) -> Result<reading::Optional> {
    if let Some(p) = flag {
        return if p.exists() {
            Ok(Ok(p.clone()))
        } else {
            Err(Error::flag(
                format!("--{name}"),
                format!("{}: no such file or folder", p.display()),
            ))
        };
    }
    let d = Path::new(default);
    Ok(if d.is_dir() {
        Ok(d.to_path_buf())
    } else {
        Err(reading::Absent {
            default: default.to_string(),
            flag: name.to_string(),
        })
    })
}

/// The real-capture test set: three frames two stops apart chosen by the frames' own metering,
/// ground truth merged from every frame, linearised by a Debevec response estimated from the
/// brackets (`hdrsynth testset --brackets --inputs auto --gt-frames all`).
pub(super) fn real_capture(brackets: &Path, out: &Path) -> Result<PathBuf> {
    use crate::capture::scan::ScanOptions;
    use crate::capture::testset::{self, BracketOptions, GtFrames, InputChoice};
    let dir = out.join("data/testset_real_capture");
    if !dir.is_dir() {
        // Built beside and renamed when complete, so an interrupted build is redone.
        let partial = out.join("data/testset_real_capture.partial");
        if partial.exists() {
            std::fs::remove_dir_all(&partial).map_err(|e| Error::io(&partial, e))?;
        }
        let opts = BracketOptions {
            // A tripod bracket may take minutes (the 550D's spans 101 s): frames group into a
            // set until an exposure repeats or an hour passes.
            scan: ScanOptions {
                max_gap_s: 3600.0,
                ..ScanOptions::default()
            },
            inputs: InputChoice::Auto,
            gt_frames: GtFrames::All,
            ..BracketOptions::default()
        };
        testset::build(brackets, &opts, &partial)?;
        std::fs::rename(&partial, &dir).map_err(|e| Error::io(&dir, e))?;
    }
    Ok(dir)
}

/// The noise ceiling of the primary test set: the triangle merge with the true response, of
/// the noisy frames and of the noise-free ones; mean over seeds of the mean over scenes of each
/// metric (`report::METRICS` order of `metrics`). The noisy half is the grid's triangle row
/// where it has one (the same merge of the same frames, scored alike): read, not run again.
pub(super) fn noise_ceiling(
    cfg: &AblateConfig,
    response: &Response,
    out: &Path,
    progress: bool,
) -> Result<[(f64, f64); 4]> {
    let triangle = (cfg.rows.iter())
        .position(|a| a.kind == AxisKind::Triangle)
        .filter(|_| cfg.columns.is_empty());
    let graded = |k: u64| {
        let r = triangle?;
        let seed = (cfg.cell_seeds(r, None).contains(&Some(k))).then_some(k);
        let path = cfg.eval_dir(r, None, seed).join(evaluate::SUMMARY_CSV);
        path.is_file().then_some(path)
    };
    // Per seed, the triangle merge of the noisy and of the noise-free frames, several at once;
    // each read back from its evaluation's summary.csv, as the grid's row is.
    let runs: Vec<(u64, bool)> = (cfg.seeds.iter())
        .flat_map(|&k| [(k, false), (k, true)])
        .collect();
    let scores = crate::experiments::at_once(ablate::GRID_JOBS, &runs, |_, &(k, clean)| {
        let summary = match graded(k).filter(|_| !clean) {
            Some(path) => path,
            None => triangle_merge(cfg, response, out, k, clean)?,
        };
        let means = crate::eval::report::read_summary_means(&summary)?;
        Ok(["psnr_t", "psnr_l", "ssim_t", "ssim_l"].map(|m| {
            (means.iter())
                .find(|(x, _)| x == m)
                .map_or(f64::NAN, |x| x.1)
        }))
    })?;
    let mut sums = [(0.0, 0.0); 4];
    for (&k, pair) in cfg.seeds.iter().zip(scores.chunks_exact(2)) {
        let (noisy, clean) = (pair[0], pair[1]);
        for mi in 0..4 {
            sums[mi].0 += noisy[mi] / cfg.seeds.len() as f64;
            sums[mi].1 += clean[mi] / cfg.seeds.len() as f64;
        }
        if progress {
            eprintln!(
                "noise ceiling, seed {k}: triangle merge PSNR-T noisy {:.2} / noise-free {:.2}",
                noisy[0], clean[0]
            );
        }
    }
    Ok(sums)
}

/// Seed k's triangle merge of the primary test set's noisy or noise-free frames with the true
/// response, evaluated into `out`; returns its summary.csv.
fn triangle_merge(
    cfg: &AblateConfig,
    response: &Response,
    out: &Path,
    k: u64,
    clean: bool,
) -> Result<PathBuf> {
    let method = ClassicalMerge {
        kind: Classical::Triangle,
        response: response.clone(),
        clean,
    };
    let dir = out.join(format!("seed{k}/{}", if clean { "clean" } else { "noisy" }));
    let partial = dir.with_extension("partial");
    if partial.exists() {
        std::fs::remove_dir_all(&partial).map_err(|e| Error::io(&partial, e))?;
    }
    evaluate::evaluate(
        &cfg.testset.dir_for(Some(k)),
        &method,
        &partial,
        &EvalOptions {
            progress: false,
            ..EvalOptions::default()
        },
    )?;
    if dir.exists() {
        std::fs::remove_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
    }
    std::fs::rename(&partial, &dir).map_err(|e| Error::io(&dir, e))?;
    Ok(dir.join(evaluate::SUMMARY_CSV))
}
