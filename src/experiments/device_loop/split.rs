//! Which scenes or regions calibrate and which are scored, and the refusal of a split in
//! which a capture would do both.

use super::*;

/// The calibration and test scans, their split checked: no capture region both calibrates
/// and is scored.
pub(super) fn split(
    opts: &LoopOptions,
    folder: &FolderScan,
) -> Result<(ScanOptions, ScanOptions, Vec<String>, Vec<String>)> {
    let all = folder.select(&opts.scan)?;
    let names: Vec<String> = all.sets.iter().map(|s| s.name.clone()).collect();
    let (cal, test) = if opts.calibration.is_empty() {
        if opts.calibration_region.is_none() || opts.test_region.is_none() {
            return Err(Error::layout(
                &opts.brackets,
                format!(
                    "name the calibration sets (--calibration; the others are the test \
                     scenes), or give --calibration-region and --test-region to split every \
                     set into two regions (sets: {})",
                    names.join(", ")
                ),
            ));
        }
        (names.clone(), names.clone())
    } else {
        let test: Vec<String> = names
            .iter()
            .filter(|n| !opts.calibration.contains(n))
            .cloned()
            .collect();
        if test.is_empty() && opts.test_region.is_none() {
            return Err(Error::layout(
                &opts.brackets,
                format!(
                    "every set ({}) calibrates; a test scene is needed that does not",
                    names.join(", ")
                ),
            ));
        }
        let test = if test.is_empty() { names.clone() } else { test };
        (opts.calibration.clone(), test)
    };
    let scan_of = |sets: &[String], region| ScanOptions {
        sets: sets.to_vec(),
        region,
        ..opts.scan.clone()
    };
    let (cal_scan, test_scan) = (
        scan_of(&cal, opts.calibration_region),
        scan_of(&test, opts.test_region),
    );
    let sources = |scan: &ScanOptions| -> Result<Vec<Source>> {
        folder
            .select(scan)?
            .sets
            .iter()
            .flat_map(|s| s.all_frames())
            .map(scan::frame_source)
            .collect()
    };
    let (a, b) = (sources(&cal_scan)?, sources(&test_scan)?);
    if let Some((c, t)) = overlapping(&a, &b).first() {
        let what = if c.sha256 == t.sha256 {
            c.file.clone()
        } else {
            format!(
                "{} (a calibration frame) and {} (a test frame) hold the same pixels: the capture",
                c.file, t.file
            )
        };
        return Err(Error::layout(
            &opts.brackets,
            format!(
                "{what} would both calibrate (pixels {:?}) and be scored (pixels {:?}): a \
                 scene never calibrates the model scored on it; choose other calibration sets \
                 or disjoint regions",
                c.pixels, t.pixels
            ),
        ));
    }
    Ok((cal_scan, test_scan, cal, test))
}

/// Record the split and the test set's options in `OUT/split.toml` on the first run, and
/// refuse a rerun that asks for another: its profiles, test set and cells would be the first
/// run's, silently.
pub(super) fn keep_split(opts: &LoopOptions, cal: &[String], test: &[String]) -> Result<()> {
    let region = |r: Option<Region>| r.map_or("whole frames".to_string(), |r| r.to_string());
    let mut text = format!(
        "# What this loop folder was made with; another split needs another folder.\n\
         brackets = {:?}\ncalibration = {:?}\ncalibration_region = {:?}\ntest = {:?}\n\
         test_region = {:?}\ninputs = {:?}\ngt_frames = {:?}\ndeclared_evs = {:?}\n\
         max_gap_s = {}\n",
        opts.brackets.display().to_string(),
        cal,
        region(opts.calibration_region),
        test,
        region(opts.test_region),
        format!("{:?}", opts.inputs),
        format!("{:?}", opts.gt_frames),
        format!("{:?}", opts.scan.evs),
        opts.scan.max_gap_s
    );
    // Written only when set, so folders made before the option read the same.
    if opts.scan.repeats {
        text += "repeats = true\n";
    }
    let path = opts.out.join("split.toml");
    if path.is_file() {
        let old = crate::io::guard::read_text(&path)?;
        if old != text {
            return Err(Error::layout(
                &path,
                "this loop folder was made with another split or test set (this file); give \
                 another --out, or delete the folder to start over",
            ));
        }
        return Ok(());
    }
    std::fs::create_dir_all(&opts.out).map_err(|e| Error::io(&opts.out, e))?;
    crate::io::atomic::write_atomic(&path, text.as_bytes())
}
