//! Import of darktable's measured noise profiles (noiseprofiles.json, flattened to CSV with
//! columns `maker,model,iso,a_R,a_G,a_B,b_R,b_G,b_B,profile_name`).
//!
//! darktable's convention is the profile's: σ²(x) = a·x + b with x the raw value normalised to
//! [0, 1], per channel, so a and b are copied verbatim. Some cameras have several profiles at
//! the same ISO (the JSON lists the model twice, or several shots per ISO), often under the
//! same `profile_name`. Rows are then told apart by `--profile-name` (the name with its
//! trailing " iso N" removed, or the full name) and by `--set K`: the K-th row at each ISO in
//! CSV order.
//!
//! darktable fits can give negative a or b (1,142 of 7,045 rows have a negative b, 24 a
//! negative a). A negative b would leave the shadows with no noise at all (the realism operator
//! clamps a·x + b at 0), yet every sensor has read noise. By default ([`NegativeRule::Floor`])
//! a negative b is replaced by the read-noise floor of [`read_noise_floor`]; negative a are kept
//! verbatim. `Verbatim` and `Zero` keep or zero every negative value. Every changed or kept
//! negative value is listed in the provenance.

use crate::error::{Error, Result};
use crate::sensor::profile::{Levels, NoiseAtIso, ProfileKind, SensorProfile};
use std::path::{Path, PathBuf};

pub const COLUMNS: [&str; 10] = [
    "maker",
    "model",
    "iso",
    "a_R",
    "a_G",
    "a_B",
    "b_R",
    "b_G",
    "b_B",
    "profile_name",
];

/// One CSV row: noise of one camera at one ISO (normalised convention).
#[derive(Clone, Debug, PartialEq)]
pub struct DarktableRow {
    pub maker: String,
    pub model: String,
    pub iso: f64,
    pub a: [f64; 3],
    pub b: [f64; 3],
    pub profile_name: String,
    /// 1-based line in the CSV file.
    pub line: usize,
}

/// `profile_name` without its trailing " iso N" ("Canon EOS 550D iso 100" → "Canon EOS 550D").
pub fn profile_family(name: &str) -> &str {
    let lower = name.to_ascii_lowercase();
    if let Some(pos) = lower.rfind(" iso ") {
        let tail = &name[pos + 5..];
        if !tail.is_empty() && tail.chars().all(|c| c.is_ascii_digit() || c == '.') {
            return name[..pos].trim_end();
        }
    }
    name
}

/// Read the whole CSV. Errors name the file and line.
pub fn read_csv(path: &Path) -> Result<Vec<DarktableRow>> {
    let text = crate::io::guard::read_text(path)?;
    parse_csv(&text, path)
}

/// The 1-based line of the record the reader places at `byte`. Not the reader's own line count:
/// csv 1.4 counts a CRLF file's lines one short, and a record's byte position may sit on the
/// line breaks (and blank lines) before it, so skip those first.
fn line_at(text: &str, byte: u64) -> usize {
    let bytes = text.as_bytes();
    let mut i = usize::try_from(byte).map_or(bytes.len(), |b| b.min(bytes.len()));
    while i < bytes.len() && matches!(bytes[i], b'\r' | b'\n') {
        i += 1;
    }
    1 + bytes[..i].iter().filter(|&&b| b == b'\n').count()
}

/// The CSV's text, parsed as [`read_csv`] parses the file `path` (named in errors).
pub fn parse_csv(text: &str, path: &Path) -> Result<Vec<DarktableRow>> {
    let text = text.trim_start_matches('\u{feff}');
    if text.is_empty() {
        return Err(Error::decode(path, "empty file"));
    }
    // Rows of another length are reported with their line below, not by the reader.
    let mut reader = csv::ReaderBuilder::new()
        .flexible(true)
        .from_reader(text.as_bytes());
    let csv_err = |e: csv::Error| {
        let line = e.position().map_or(1, |p| line_at(text, p.byte()));
        Error::decode(path, format!("line {line}: {e}"))
    };
    let header = reader.headers().map_err(csv_err)?.clone();
    let col = |name: &str| header.iter().position(|h| h.trim() == name);
    let mut idx = [0usize; 10];
    for (k, name) in COLUMNS.iter().enumerate() {
        idx[k] = col(name).ok_or_else(|| {
            Error::decode(
                path,
                format!(
                    "line 1: no column '{name}' (expected columns {})",
                    COLUMNS.join(",")
                ),
            )
        })?;
    }
    let mut rows = Vec::new();
    for record in reader.records() {
        let f = record.map_err(csv_err)?;
        if f.len() == 1 && f[0].trim().is_empty() {
            continue;
        }
        let line_no = f.position().map_or(0, |p| line_at(text, p.byte()));
        let at = |msg: String| Error::decode(path, format!("line {line_no}: {msg}"));
        if f.len() != header.len() {
            return Err(at(format!(
                "{} fields, the header has {}",
                f.len(),
                header.len()
            )));
        }
        let num = |k: usize| -> Result<f64> {
            let s = f[idx[k]].trim();
            s.parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| at(format!("{} = '{s}' is not a finite number", COLUMNS[k])))
        };
        let iso = num(2)?;
        if iso <= 0.0 {
            return Err(at(format!("iso {iso} must be > 0")));
        }
        rows.push(DarktableRow {
            maker: f[idx[0]].trim().to_string(),
            model: f[idx[1]].trim().to_string(),
            iso,
            a: [num(3)?, num(4)?, num(5)?],
            b: [num(6)?, num(7)?, num(8)?],
            profile_name: f[idx[9]].trim().to_string(),
            line: line_no,
        });
    }
    Ok(rows)
}

/// Which camera and which of its profiles.
#[derive(Clone, Debug, Default)]
pub struct Query {
    pub maker: String,
    pub model: String,
    /// Profile family (name without " iso N") or full profile name, case-insensitive.
    pub profile_name: Option<String>,
    /// 1-based: the K-th row at each ISO, in CSV order.
    pub set: Option<usize>,
}

/// The rows picked by [`select`], ascending ISO, with a description for provenance.
#[derive(Clone, Debug)]
pub struct Selection {
    pub rows: Vec<DarktableRow>,
    /// Distinct profile families among the rows.
    pub families: Vec<String>,
    /// The set picked and how many there were (1, 1 when no ISO is duplicated).
    pub set: usize,
    pub sets: usize,
}

/// Select one camera's profile: case-insensitive exact maker and model; then `profile_name`;
/// then, where ISOs still repeat, the set. Errors list the choices.
pub fn select(rows: &[DarktableRow], q: &Query, csv: &Path) -> Result<Selection> {
    let camera = format!("{} {}", q.maker, q.model);
    let cam = camera_rows(rows, q, csv)?;
    let picked: Vec<&DarktableRow> = match &q.profile_name {
        None => cam.clone(),
        Some(p) => named_rows(&cam, p, &camera, csv)?,
    };
    let (sets, seen) = number_sets(&picked);
    let n_sets = sets.len();
    let set = match q.set {
        None if n_sets > 1 => {
            let mut dup: Vec<f64> = seen
                .iter()
                .filter(|(_, n)| *n > 1)
                .map(|(i, _)| *i)
                .collect();
            dup.sort_by(f64::total_cmp);
            return Err(Error::config(
                csv,
                format!(
                    "{camera}: several darktable profiles share ISO {}; choose one with \
                     --profile-name (names: {}) and/or --set K (rows at each ISO numbered in \
                     CSV order):\n{}",
                    dup.iter()
                        .map(|i| format!("{i}"))
                        .collect::<Vec<_>>()
                        .join(", "),
                    quote_list(&families_of(&picked)),
                    describe_sets(&sets)
                ),
            ));
        }
        None => 1,
        Some(k) if k == 0 || k > n_sets => {
            return Err(Error::config(
                csv,
                format!(
                    "{camera}: --set {k} does not exist; there {} {n_sets} set(s):\n{}",
                    if n_sets == 1 { "is" } else { "are" },
                    describe_sets(&sets)
                ),
            ));
        }
        Some(k) => k,
    };
    let mut rows: Vec<DarktableRow> = sets[set - 1].iter().map(|r| (*r).clone()).collect();
    rows.sort_by(|a, b| a.iso.total_cmp(&b.iso));
    let families = families_of(&sets[set - 1]);
    Ok(Selection {
        rows,
        families,
        set,
        sets: n_sets,
    })
}

/// Names (maker, model, profile) match case-insensitively, surrounding spaces ignored.
fn same_name(a: &str, b: &str) -> bool {
    a.trim().eq_ignore_ascii_case(b.trim())
}

/// The rows of the query's maker and model; an error lists the makers, or the maker's models.
fn camera_rows<'a>(
    rows: &'a [DarktableRow],
    q: &Query,
    csv: &Path,
) -> Result<Vec<&'a DarktableRow>> {
    let maker_rows: Vec<&DarktableRow> = rows
        .iter()
        .filter(|r| same_name(&r.maker, &q.maker))
        .collect();
    if maker_rows.is_empty() {
        let mut makers: Vec<&str> = rows.iter().map(|r| r.maker.as_str()).collect();
        makers.sort_unstable();
        makers.dedup();
        return Err(Error::config(
            csv,
            format!("no maker '{}' (makers: {})", q.maker, makers.join(", ")),
        ));
    }
    let cam: Vec<&DarktableRow> = maker_rows
        .iter()
        .copied()
        .filter(|r| same_name(&r.model, &q.model))
        .collect();
    if cam.is_empty() {
        let mut models: Vec<&str> = maker_rows.iter().map(|r| r.model.as_str()).collect();
        models.sort_unstable();
        models.dedup();
        return Err(Error::config(
            csv,
            format!(
                "maker '{}' has no model '{}' (models: {})",
                q.maker,
                q.model,
                models.join(", ")
            ),
        ));
    }
    Ok(cam)
}

/// The camera's rows whose profile family or full profile name is `name`; an error lists the
/// camera's families.
fn named_rows<'a>(
    cam: &[&'a DarktableRow],
    name: &str,
    camera: &str,
    csv: &Path,
) -> Result<Vec<&'a DarktableRow>> {
    let v: Vec<&DarktableRow> = cam
        .iter()
        .copied()
        .filter(|r| {
            same_name(profile_family(&r.profile_name), name) || same_name(&r.profile_name, name)
        })
        .collect();
    if v.is_empty() {
        return Err(Error::config(
            csv,
            format!(
                "{camera}: no profile named '{name}' (profile names: {})",
                quote_list(&families_of(cam))
            ),
        ));
    }
    Ok(v)
}

/// Distinct profile families of `rs`, in order of first appearance.
fn families_of(rs: &[&DarktableRow]) -> Vec<String> {
    let mut fams: Vec<String> = Vec::new();
    for r in rs {
        let f = profile_family(&r.profile_name).to_string();
        if !fams.contains(&f) {
            fams.push(f);
        }
    }
    fams
}

/// Rows numbered at each ISO in CSV order: set k = the k-th row at each ISO. Also each ISO
/// with its row count.
fn number_sets<'a>(picked: &[&'a DarktableRow]) -> (Vec<Vec<&'a DarktableRow>>, Vec<(f64, usize)>) {
    let mut sets: Vec<Vec<&DarktableRow>> = Vec::new();
    let mut seen: Vec<(f64, usize)> = Vec::new();
    for r in picked {
        let k = match seen.iter_mut().find(|(iso, _)| *iso == r.iso) {
            Some((_, n)) => {
                *n += 1;
                *n - 1
            }
            None => {
                seen.push((r.iso, 1));
                0
            }
        };
        if sets.len() <= k {
            sets.push(Vec::new());
        }
        sets[k].push(r);
    }
    (sets, seen)
}

/// One line per set for the errors: its ISOs, rows, CSV lines and profile names.
fn describe_sets(sets: &[Vec<&DarktableRow>]) -> String {
    sets.iter()
        .enumerate()
        .map(|(k, s)| {
            let mut isos: Vec<f64> = s.iter().map(|r| r.iso).collect();
            isos.sort_by(f64::total_cmp);
            let lines: Vec<usize> = s.iter().map(|r| r.line).collect();
            format!(
                "  --set {}: ISO {} ({} rows, CSV lines {}–{}, profile names {})",
                k + 1,
                isos.iter()
                    .map(|i| format!("{i}"))
                    .collect::<Vec<_>>()
                    .join(", "),
                s.len(),
                lines.iter().min().unwrap_or(&0),
                lines.iter().max().unwrap_or(&0),
                quote_list(&families_of(s))
            )
        })
        .collect::<Vec<_>>()
        .join("\n")
}

fn quote_list(v: &[String]) -> String {
    v.iter()
        .map(|s| format!("'{s}'"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// What the import writes for darktable's negative values.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum NegativeRule {
    /// b < 0 replaced by [`read_noise_floor`]; a < 0 kept verbatim (the variance a·x + b stays
    /// positive near black, where the replaced b dominates).
    #[default]
    Floor,
    /// Every value as darktable has it (the realism operator clamps a·x + b at 0, so a negative
    /// b means no noise at all below x = −b/a).
    Verbatim,
    /// Every negative a or b written as 0.
    Zero,
}

/// Quantisation noise of the raw ADC in the normalised convention: a uniform rounding error of
/// one DN has variance 1/12 DN², i.e. 1/(12·(W − B)²) for x = DN / (W − B).
pub fn quantisation_floor(levels: &Levels) -> f64 {
    let range = levels.white_level - levels.black_level;
    1.0 / (12.0 * range * range)
}

/// The b written for a negative b of channel `c` at row `i` (rows in ascending ISO): the
/// largest positive b of the same channel at a lower ISO, and at least the quantisation floor.
///
/// Why: b is the variance at zero signal, the read noise referred to the raw output. That is
/// g²·σ²_pre + σ²_post with the analogue gain g rising with ISO, so it cannot fall as ISO rises
/// and a b measured at a lower ISO is a lower bound; no digitised signal has less than the
/// ADC's rounding noise. Returns the value and, where it came from a lower ISO, that ISO.
pub fn read_noise_floor(
    rows: &[DarktableRow],
    i: usize,
    c: usize,
    levels: &Levels,
) -> (f64, Option<f64>) {
    let q = quantisation_floor(levels);
    let lower = rows[..i]
        .iter()
        .filter(|r| r.iso < rows[i].iso && r.b[c] > 0.0)
        .max_by(|x, y| x.b[c].total_cmp(&y.b[c]));
    match lower {
        Some(r) if r.b[c] > q => (r.b[c], Some(r.iso)),
        _ => (q, None),
    }
}

const CH: [&str; 3] = ["R", "G", "B"];

/// The selection as profile noise entries under `rule`, with one note per negative value
/// (what it was, its CSV line, and what was written instead). `levels` give the quantisation
/// floor of the raw ADC.
pub fn to_noise(
    sel: &Selection,
    rule: NegativeRule,
    levels: &Levels,
) -> (Vec<NoiseAtIso>, Vec<String>) {
    let mut notes = Vec::new();
    let mut noise = Vec::new();
    for (i, r) in sel.rows.iter().enumerate() {
        let mut a = r.a;
        let mut b = r.b;
        for c in 0..3 {
            let at = |name: &str, v: f64| {
                format!("ISO {} {name}_{} = {v:e} (line {})", r.iso, CH[c], r.line)
            };
            if r.a[c] < 0.0 {
                match rule {
                    NegativeRule::Zero => {
                        a[c] = 0.0;
                        notes.push(format!("{} → 0", at("a", r.a[c])));
                    }
                    _ => notes.push(format!("{} kept", at("a", r.a[c]))),
                }
            }
            if r.b[c] < 0.0 {
                match rule {
                    NegativeRule::Floor => {
                        let (v, from) = read_noise_floor(&sel.rows, i, c, levels);
                        b[c] = v;
                        let why = match from {
                            Some(iso) => format!("b_{} at ISO {iso}", CH[c]),
                            None => "quantisation floor".to_string(),
                        };
                        notes.push(format!("{} → {v:e} ({why})", at("b", r.b[c])));
                    }
                    NegativeRule::Zero => {
                        b[c] = 0.0;
                        notes.push(format!("{} → 0", at("b", r.b[c])));
                    }
                    NegativeRule::Verbatim => notes.push(format!("{} kept", at("b", r.b[c]))),
                }
            }
        }
        noise.push(NoiseAtIso {
            iso: r.iso,
            a,
            b,
            a_stderr: None,
            b_stderr: None,
        });
    }
    (noise, notes)
}

/// Text for `provenance.noise`.
pub fn provenance(
    q: &Query,
    sel: &Selection,
    csv: &Path,
    notes: &[String],
    rule: NegativeRule,
    levels: &Levels,
) -> String {
    let first = sel.rows.first();
    let last = sel.rows.last();
    let lines: Vec<usize> = sel.rows.iter().map(|r| r.line).collect();
    let mut s = format!(
        "darktable's noiseprofiles.json (darktable project, GPL-3+ data), flattened CSV {}: \
         maker '{}', model '{}', profile {}{}; {} ISO(s) {}–{}, CSV lines {}; a and b copied \
         from the CSV (darktable's normalised convention σ² = a·x + b, x in [0, 1])",
        csv.display(),
        first.map_or(q.maker.as_str(), |r| r.maker.as_str()),
        first.map_or(q.model.as_str(), |r| r.model.as_str()),
        quote_list(&sel.families),
        if sel.sets > 1 {
            format!(
                " (set {} of {} at duplicated ISOs, by CSV order)",
                sel.set, sel.sets
            )
        } else {
            String::new()
        },
        sel.rows.len(),
        first.map_or(0.0, |r| r.iso),
        last.map_or(0.0, |r| r.iso),
        lines
            .iter()
            .map(|l| l.to_string())
            .collect::<Vec<_>>()
            .join(","),
    );
    if notes.is_empty() {
        s.push_str(", no negative values");
        return s;
    }
    let how = match rule {
        NegativeRule::Floor => format!(
            "negative b replaced by the read-noise floor (the largest positive b of the same \
             channel at a lower ISO, at least the ADC quantisation floor 1/(12·(W−B)²) = {:e}; \
             docs/noise.md), negative a kept verbatim (the realism operator clamps a·x + b at 0)",
            quantisation_floor(levels)
        ),
        NegativeRule::Verbatim => {
            "negative values kept verbatim (`--negative verbatim`; the realism operator clamps \
             a·x + b at 0)"
                .to_string()
        }
        NegativeRule::Zero => "negative values written as 0 (`--negative zero`)".to_string(),
    };
    s.push_str(&format!("; {how}: {}", notes.join("; ")));
    s
}

/// Everything `hdrsynth profile import-darktable` needs.
#[derive(Clone, Debug)]
pub struct ImportRequest {
    pub csv: PathBuf,
    pub query: Query,
    pub levels: Levels,
    /// Where the levels come from (provenance.levels).
    pub levels_source: String,
    pub rule: NegativeRule,
    /// The profile to write: an existing one gets noise, levels and their provenance replaced.
    pub out: PathBuf,
    /// Name and kind of a new profile (default "MAKER MODEL", measured).
    pub name: Option<String>,
    pub kind: ProfileKind,
}

/// What [`import`] did.
#[derive(Clone, Debug)]
pub struct ImportOutcome {
    pub profile: SensorProfile,
    pub created: bool,
    pub selection: Selection,
    /// One note per negative value in the CSV rows (kept, replaced or zeroed).
    pub notes: Vec<String>,
}

/// Import a camera's noise from the CSV into `req.out` (created or updated, atomically).
pub fn import(req: &ImportRequest) -> Result<ImportOutcome> {
    if req.levels_source.trim().is_empty() {
        return Err(Error::flag(
            "--levels-source",
            "is empty: the levels need a source",
        ));
    }
    let rows = read_csv(&req.csv)?;
    let sel = select(&rows, &req.query, &req.csv)?;
    let (noise, notes) = to_noise(&sel, req.rule, &req.levels);
    let noise_source = provenance(&req.query, &sel, &req.csv, &notes, req.rule, &req.levels);
    let (mut profile, existed) = SensorProfile::load_or_create(&req.out, || {
        let name = req
            .name
            .clone()
            .unwrap_or_else(|| format!("{} {}", sel.rows[0].maker, sel.rows[0].model));
        let mut p = SensorProfile::from_noise(
            &name,
            req.levels.clone(),
            &req.levels_source,
            noise.clone(),
            &noise_source,
        );
        p.kind = req.kind;
        Ok::<_, Error>(p)
    })?;
    if existed {
        profile.noise = noise;
        profile.provenance.noise = noise_source;
        profile.levels = req.levels.clone();
        profile.provenance.levels = req.levels_source.clone();
    }
    let created = !existed;
    profile.save(&req.out)?;
    Ok(ImportOutcome {
        profile,
        created,
        selection: sel,
        notes,
    })
}

impl ImportOutcome {
    /// The command's report: what was written from where, the noise per ISO, and every note
    /// on a negative value.
    pub fn report(&self, req: &ImportRequest) -> String {
        let (profile, sel) = (&self.profile, &self.selection);
        let mut report = format!(
            "{} {} ({}) from {}: {} ISO(s) {}–{}{}\n",
            if self.created { "created" } else { "updated" },
            req.out.display(),
            profile.kind,
            req.csv.display(),
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
        let rule = format!("{:?}", req.rule).to_lowercase();
        for c in &self.notes {
            report.push_str(&format!("negative ({rule}): {c}\n"));
        }
        report
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const HEADER: &str = "maker,model,iso,a_R,a_G,a_B,b_R,b_G,b_B,profile_name";
    const ROW: &str = "Canon,EOS 550D,100,1e-6,1e-6,1e-6,2e-8,2e-8,2e-8,p";

    /// Rows and errors carry the line as an editor shows it, for LF and CRLF files (darktable's
    /// own CSV is CRLF) and across blank lines.
    #[test]
    fn lines_are_counted_as_an_editor_counts_them() {
        for eol in ["\n", "\r\n"] {
            let text = [HEADER, ROW, "", ROW, "Canon,EOS 550D,x,1,1,1,1,1,1,p"].join(eol);
            let err = parse_csv(&text, Path::new("n.csv"))
                .unwrap_err()
                .to_string();
            assert!(err.contains("line 5: iso = 'x'"), "{eol:?}: {err}");
            let good = [HEADER, ROW, "", ROW].join(eol);
            let rows = parse_csv(&good, Path::new("n.csv")).unwrap();
            let lines: Vec<usize> = rows.iter().map(|r| r.line).collect();
            assert_eq!(lines, [2, 4], "{eol:?}");
        }
    }
}
