//! Writing the test set: per set, the inputs' and ground-truth frames' codes, their
//! alignment, the merged ground truth, the files and the record.

use super::*;
use crate::capture::linearise::linearise;

/// A stop rounded as exposure.txt writes it, so the merge uses exactly what the field's code
/// will read back.
fn written_stop(s: f64) -> f64 {
    format!("{s:.6}").parse().unwrap_or(0.0)
}

pub(super) fn build_sets(
    sets: &[scan::BracketSet],
    selections: &[InputSelection],
    lin: &Linearise,
    how: Encoding,
    opts: &BracketOptions,
    out: &Path,
    mut notes: Vec<String>,
) -> Result<BracketSummary> {
    let mut built = Vec::with_capacity(sets.len());
    for (set, sel) in sets.iter().zip(selections) {
        built.push(build_set(set, sel, lin, how, opts, out, &mut notes)?);
    }
    Ok(BracketSummary { sets: built, notes })
}

/// Which inputs and ground-truth frames a set of more than three frames (or a chosen
/// selection) took.
fn selection_note(
    set: &scan::BracketSet,
    sel: &InputSelection,
    n_gt: usize,
    n_dropped: usize,
) -> String {
    format!(
        "set '{}': {} frames; inputs {:?} ({}); ground truth from {n_gt} frame(s){}{}",
        set.name,
        set.frames.len(),
        sel.indices,
        sel.how,
        if n_gt == sel.indices.len() {
            " (the inputs' own merge: it holds their noise, so a network that denoises them is \
             scored down; capture more frames per set for a ground truth independent of the \
             inputs)"
        } else {
            ""
        },
        if n_dropped == 0 {
            String::new()
        } else {
            format!(", dropped {n_dropped}")
        }
    )
}

/// The resolved `--encode` and its record.
#[derive(Clone, Copy)]
pub(super) struct Encoding<'a> {
    pub(super) encode: &'a Encode,
    pub(super) record: &'a FrameEncoding,
}

/// One set's frames as the merge takes them: the 16-bit γ codes of the ground-truth frames,
/// their codes as stored (only for the hat merge), the inputs as written when not the γ codes
/// (`--encode device` or a profile's curve; in input order) and the reference's clipped or dark
/// fraction.
struct SetCodes {
    codes: Vec<Image>,
    stored: Vec<Image>,
    written: Vec<Image>,
    reference_bad: f64,
}

/// Build one set's folder (inputs, exposure.txt, merged ground truth, record).
fn build_set(
    set: &scan::BracketSet,
    sel: &InputSelection,
    lin: &Linearise,
    how: Encoding,
    opts: &BracketOptions,
    out: &Path,
    notes: &mut Vec<String>,
) -> Result<BuiltBracketSet> {
    let idx = sel.indices;
    let MergedFrames {
        gt_idx,
        dropped,
        ref_pos,
        stops,
    } = merged_frames(set, sel, opts, notes);
    let chosen: Vec<&BracketFrame> = idx.iter().map(|&i| &set.frames[i]).collect();
    // The hat merge weighs each frame by its code values as stored: kept, aligned alike.
    let hat = Hat::of(gt_idx != idx, opts.gt_frames);
    let SetCodes {
        mut codes,
        mut stored,
        mut written,
        reference_bad,
    } = set_codes(set, &gt_idx, idx, ref_pos, lin, hat != Hat::No, how.encode)?;
    let mut gt_shifts: Vec<Option<[i32; 2]>> = vec![None; gt_idx.len()];
    if let Some(mtb) = opts.align {
        let kept = [&mut codes, &mut stored, &mut written];
        gt_shifts = aligned(set, kept, (&gt_idx, idx, ref_pos), mtb)?;
    }
    let (w, h) = scan::scorable_size(&set.frames[idx[1]], &codes[ref_pos])?;
    let pos = idx.map(|i| gt_idx.iter().position(|&g| g == i).unwrap_or(0));
    let inputs: [&Image; 3] = if written.is_empty() {
        pos.map(|p| &codes[p])
    } else {
        [&written[0], &written[1], &written[2]]
    };
    // Kalantari's weights come from the reference as the inputs store it.
    let (hdr, gt_merge) = merge_set(&codes, &stored, &stops, pos, inputs[1], hat)?;
    let set_dir = out.join(&set.name);
    write_set_files(&set_dir, inputs, &stops, pos, &hdr)?;
    let record = BuiltBracketSet {
        name: set.name.clone(),
        width: w,
        height: h,
        grouping: set.grouping.clone(),
        exposure_source: set.exposure_source.clone(),
        response: if gt_idx.iter().all(|&i| set.frames[i].kind == FrameKind::Dng) {
            "linear raw (DNG black/white levels)".to_string()
        } else {
            opts.response.describe()
        },
        encoding: how.record.describe(),
        inputs: idx.to_vec(),
        selection: sel.how.clone(),
        reference_clipped_or_dark: reference_bad,
        gt_merge,
        gt_dynamic_range_stops: crate::io::dynamic_range_stops(&hdr, 0.1, 99.9).unwrap_or(0.0),
        frames: chosen
            .iter()
            .zip(FRAME_NAMES)
            .zip(pos)
            .map(|((f, name), p)| RecordFrame {
                source: f.path.clone(),
                written: name.to_string(),
                stop: stops[p],
                exposure_time_s: f.exif.exposure_time,
                iso: f.exif.iso,
            })
            .collect(),
        ground_truth: gt_idx
            .iter()
            .zip(&stops)
            .zip(&gt_shifts)
            .map(|((&i, &stop), &shift)| GtRecordFrame {
                source: set.frames[i].path.clone(),
                index: i,
                stop,
                input: idx.contains(&i),
                shift,
            })
            .collect(),
        dropped,
        shifts: if opts.align.is_some() {
            pos.iter().filter_map(|&p| gt_shifts[p]).collect()
        } else {
            Vec::new()
        },
        sources: scan::set_sources(set)?,
    };
    let toml =
        toml::to_string_pretty(&record).map_err(|e| Error::encode(set_dir.join(RECORD), e))?;
    crate::io::atomic::write_atomic(&set_dir.join(RECORD), toml.as_bytes())?;
    Ok(record)
}

/// The frames a set's ground truth merges (indices into the set), the frames it leaves out,
/// the reference's position among the merged frames and their stops relative to the shortest
/// input, rounded as exposure.txt writes them.
struct MergedFrames {
    gt_idx: Vec<usize>,
    dropped: Vec<PathBuf>,
    ref_pos: usize,
    stops: Vec<f64>,
}

fn merged_frames(
    set: &scan::BracketSet,
    sel: &InputSelection,
    opts: &BracketOptions,
    notes: &mut Vec<String>,
) -> MergedFrames {
    let n = set.frames.len();
    let idx = sel.indices;
    let gt_idx: Vec<usize> = match opts.gt_frames {
        GtFrames::Inputs => idx.to_vec(),
        GtFrames::All | GtFrames::Others => (0..n).collect(),
    };
    let dropped: Vec<PathBuf> = (0..n)
        .filter(|i| !gt_idx.contains(i))
        .map(|i| set.frames[i].path.clone())
        .collect();
    if n > 3 || opts.inputs != InputChoice::Spread || gt_idx.len() == idx.len() {
        notes.push(selection_note(set, sel, gt_idx.len(), dropped.len()));
    }
    let ref_pos = gt_idx.iter().position(|&i| i == idx[1]).unwrap_or(0);
    let shortest = set.frames[idx[0]].stop;
    let stops = gt_idx
        .iter()
        .map(|&i| written_stop(set.frames[i].stop - shortest))
        .collect();
    MergedFrames {
        gt_idx,
        dropped,
        ref_pos,
        stops,
    }
}

/// [`align_codes`] on a set's kept images (the γ codes, the stored codes, the written
/// inputs), refused where the shifts leave no common area; each merged frame's shift.
fn aligned(
    set: &scan::BracketSet,
    [codes, stored, written]: [&mut Vec<Image>; 3],
    at: (&[usize], [usize; 3], usize),
    mtb: MtbOptions,
) -> Result<Vec<Option<[i32; 2]>>> {
    let (_, idx, ref_pos) = at;
    let s = align_codes(codes, stored, written, at, mtb);
    if codes[ref_pos].width == 0 || codes[ref_pos].height == 0 {
        return Err(Error::layout(
            &set.frames[idx[1]].path,
            format!("set '{}': MTB shifts {s:?} leave no common area", set.name),
        ));
    }
    Ok(s.iter().map(|&(x, y)| Some([x, y])).collect())
}

/// MTB-align every ground-truth frame's codes to the reference (at `ref_pos`) and crop all
/// kept images alike (the stored codes of the hat merge, the written inputs `idx`); returns
/// the shifts. MTB runs on the γ-encoded frames: its median thresholds need no response.
fn align_codes(
    codes: &mut Vec<Image>,
    stored: &mut Vec<Image>,
    written: &mut [Image],
    (gt_idx, idx, ref_pos): (&[usize], [usize; 3], usize),
    mtb: MtbOptions,
) -> Vec<(i32, i32)> {
    let s: Vec<(i32, i32)> = codes
        .iter()
        .map(|c| align::mtb_shift(&codes[ref_pos], c, mtb))
        .collect();
    let region = align::common_region(codes[ref_pos].width, codes[ref_pos].height, &s);
    *codes = align::apply_shifts(codes, &s);
    if !stored.is_empty() {
        *stored = align::apply_shifts(stored, &s);
    }
    for (img, &i) in written.iter_mut().zip(&idx) {
        let p = gt_idx.iter().position(|&g| g == i).unwrap_or(0);
        *img = align::crop_shifted(img, s[p], region);
    }
    s
}

/// Each ground-truth frame `gt_idx` of `set`: decode → (metering, for the reference, the
/// middle of the inputs `idx`) → linear → code linear^(1/γ) on 16 bits; only those codes (and,
/// for the hat merge, the stored codes; for the inputs, what `encode` writes when it is not
/// the γ code) are kept. The frames must all have the reference's size.
fn set_codes(
    set: &scan::BracketSet,
    gt_idx: &[usize],
    idx: [usize; 3],
    ref_pos: usize,
    lin: &Linearise,
    hat: bool,
    encode: &Encode,
) -> Result<SetCodes> {
    let ref_idx = idx[1];
    let inv_g = 1.0 / FIELD_GAMMA;
    let sixteen = |v: f32| (v.clamp(0.0, 1.0) * 65535.0).round() / 65535.0;
    let mut codes: Vec<Image> = Vec::with_capacity(gt_idx.len());
    let mut stored: Vec<Image> = Vec::new();
    let mut written: Vec<Option<Image>> = vec![None; 3];
    let mut reference_bad = 0.0;
    for &i in gt_idx {
        let f = &set.frames[i];
        let code = code_frame(f)?;
        if i == ref_idx {
            reference_bad = clipped_or_dark(&code);
            refuse_sceneless(set, f, reference_bad)?;
        }
        if hat {
            stored.push(code.clone());
        }
        let input = idx.iter().position(|&k| k == i);
        if let (Some(k), Encode::Device) = (input, encode) {
            written[k] = Some(code.map(sixteen));
        }
        let linear = linearise(f, code, lin);
        if let (Some(k), Encode::Curve(r)) = (input, encode) {
            written[k] = Some(linear.map(|v| sixteen(r.apply(f64::from(v)) as f32)));
        }
        codes.push(linear.map(|v| sixteen(v.clamp(0.0, 1.0).powf(inv_g))));
    }
    let written: Vec<Image> = written.into_iter().flatten().collect();
    let (w, h) = (codes[ref_pos].width, codes[ref_pos].height);
    for (&i, img) in gt_idx.iter().zip(&codes) {
        if (img.width, img.height) != (w, h) {
            return Err(Error::layout(
                &set.frames[i].path,
                format!(
                    "{}×{}, but the set's reference frame {} is {w}×{h}",
                    img.width,
                    img.height,
                    set.frames[ref_idx].path.display()
                ),
            ));
        }
    }
    Ok(SetCodes {
        codes,
        stored,
        written,
        reference_bad,
    })
}

/// Which weighted merge a set's ground truth is, when it is not the inputs' triangle merge.
#[derive(Clone, Copy, PartialEq)]
enum Hat {
    No,
    All,
    /// The frames that are not inputs where they reach, every frame elsewhere.
    Others,
}

impl Hat {
    /// The merge for a set whose ground-truth frames are more than its inputs (`more`).
    fn of(more: bool, gt: GtFrames) -> Hat {
        match (more, gt) {
            (false, _) => Hat::No,
            (true, GtFrames::Others) => Hat::Others,
            (true, _) => Hat::All,
        }
    }
}

/// The ground truth and how it was merged: Kalantari's triangle merge of the three inputs at
/// positions `pos` (weights from `weights`, the reference as written), or (`hat`) the weighted
/// merge of every frame, or of the frames that are not inputs where they reach.
fn merge_set(
    codes: &[Image],
    stored: &[Image],
    stops: &[f64],
    pos: [usize; 3],
    weights: &Image,
    hat: Hat,
) -> Result<(Image, String)> {
    if hat == Hat::Others {
        let times: Vec<f64> = stops.iter().map(|s| s.exp2()).collect();
        let all = hat_merge(codes, stored, &times, FIELD_GAMMA)?;
        let keep: Vec<usize> = (0..codes.len()).filter(|i| !pos.contains(i)).collect();
        let pick = |v: &[Image]| keep.iter().map(|&i| v[i].clone()).collect::<Vec<_>>();
        let kept_times: Vec<f64> = keep.iter().map(|&i| times[i]).collect();
        let (others, covered) =
            hat_merge_covered(&pick(codes), &pick(stored), &kept_times, FIELD_GAMMA)?;
        let data: Vec<f32> = others
            .data
            .iter()
            .zip(&all.data)
            .zip(&covered)
            .map(|((&o, &a), &c)| if c { o } else { a })
            .collect();
        let share = covered.iter().filter(|&&c| c).count() as f64 / covered.len().max(1) as f64;
        let hdr = Image::from_vec(all.width, all.height, data);
        return Ok((
            hdr,
            format!(
                "weighted merge (as `all`) of the {} frames that are not inputs where they \
                 record the value ({:.1} % of the values), of all {} frames elsewhere",
                keep.len(),
                100.0 * share,
                codes.len()
            ),
        ));
    }
    Ok(if hat == Hat::No {
        let times = pos.map(|p| stops[p].exp2() as f32);
        let g = f64::from(FIELD_GAMMA);
        (
            ground_truth::triangle_merge_weighted(
                &pos.map(|p| codes[p].clone()),
                weights,
                times,
                |v| v.powf(g),
            )?,
            "Kalantari's triangle merge of the three inputs (weights from the reference's \
             value as written)"
                .to_string(),
        )
    } else {
        let times: Vec<f64> = stops.iter().map(|s| s.exp2()).collect();
        (
            hat_merge(codes, stored, &times, FIELD_GAMMA)?,
            format!(
                "weighted merge of all {} frames: w = (1 − |2ẑ − 1|) · t per frame and \
                 channel, ẑ the code the frame is expected to record at the merged value \
                 ({HAT_REFINEMENTS} refinements of the merge weighted by the recorded codes), \
                 0 where ẑ ≤ {DARK_CODE}/255 or ≥ {CLIPPED_CODE}/255 and where the recorded \
                 code is clipped",
                codes.len()
            ),
        )
    })
}

/// The set's folder: the three inputs (16-bit), exposure.txt and the ground truth.
fn write_set_files(
    set_dir: &Path,
    inputs: [&Image; 3],
    stops: &[f64],
    pos: [usize; 3],
    hdr: &Image,
) -> Result<()> {
    std::fs::create_dir_all(set_dir).map_err(|e| Error::io(set_dir, e))?;
    for (img, name) in inputs.into_iter().zip(FRAME_NAMES) {
        write_ldr(&set_dir.join(name), img, BitDepth::Sixteen)?;
    }
    let expo = set_dir.join(crate::data::layout::kalantari::EXPOSURE_FILE);
    let text = pos
        .iter()
        .map(|&p| format!("{}", stops[p]))
        .collect::<Vec<_>>()
        .join("\n")
        + "\n";
    crate::io::atomic::write_atomic(&expo, text.as_bytes())?;
    write_hdr(&set_dir.join(crate::data::layout::kalantari::GT_FILE), hdr)
}
