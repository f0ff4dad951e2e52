//! Import of darktable's measured noise profiles (noiseprofiles.json, flattened to CSV with
//! columns `maker,model,iso,a_R,a_G,a_B,b_R,b_G,b_B,profile_name`).
//!
//! darktable's convention is the profile's: σ²(x) = a·x + b with x the raw value normalised to
//! [0, 1], per channel, so a and b are copied verbatim. Some cameras have several profiles at
//! the same ISO (the JSON lists the model twice, or several shots per ISO), often under the
//! same `profile_name`. Rows are then told apart by `--profile-name` (the name with its
//! trailing " iso N" removed, or the full name) and by `--set K`: the K-th row at each ISO in
//! CSV order. darktable fits can give negative a or b (1,155 of 7,045 rows). They are copied
//! verbatim by default (the realism operator clamps the variance a·x + b at 0) and listed in
//! the provenance; `--clamp-negative` writes them as 0 instead.

use crate::error::{Error, Result};
use crate::sensor::profile::NoiseAtIso;
use std::path::Path;

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

/// Split one CSV line; fields may be double-quoted ("" inside quotes is a quote).
fn split_csv_line(line: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut cur = String::new();
    let mut quoted = false;
    let mut chars = line.chars().peekable();
    while let Some(ch) = chars.next() {
        match ch {
            '"' if quoted && chars.peek() == Some(&'"') => {
                cur.push('"');
                chars.next();
            }
            '"' => quoted = !quoted,
            ',' if !quoted => out.push(std::mem::take(&mut cur)),
            _ => cur.push(ch),
        }
    }
    out.push(cur);
    out
}

/// Read the whole CSV. Errors name the file and line.
pub fn read_csv(path: &Path) -> Result<Vec<DarktableRow>> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let mut lines = text.lines().enumerate();
    let Some((_, header)) = lines.next() else {
        return Err(Error::decode(path, "empty file"));
    };
    let header = split_csv_line(header.trim_start_matches('\u{feff}'));
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
    for (i, line) in lines {
        let line_no = i + 1;
        if line.trim().is_empty() {
            continue;
        }
        let f = split_csv_line(line);
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
    let eq = |a: &str, b: &str| a.trim().eq_ignore_ascii_case(b.trim());
    let camera = format!("{} {}", q.maker, q.model);
    let maker_rows: Vec<&DarktableRow> = rows.iter().filter(|r| eq(&r.maker, &q.maker)).collect();
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
        .filter(|r| eq(&r.model, &q.model))
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
    let families_of = |rs: &[&DarktableRow]| {
        let mut fams: Vec<String> = Vec::new();
        for r in rs {
            let f = profile_family(&r.profile_name).to_string();
            if !fams.contains(&f) {
                fams.push(f);
            }
        }
        fams
    };
    let all_families = families_of(&cam);
    let picked: Vec<&DarktableRow> = match &q.profile_name {
        None => cam.clone(),
        Some(p) => {
            let v: Vec<&DarktableRow> = cam
                .iter()
                .copied()
                .filter(|r| eq(profile_family(&r.profile_name), p) || eq(&r.profile_name, p))
                .collect();
            if v.is_empty() {
                return Err(Error::config(
                    csv,
                    format!(
                        "{camera}: no profile named '{p}' (profile names: {})",
                        quote_list(&all_families)
                    ),
                ));
            }
            v
        }
    };

    // Number rows at each ISO in CSV order: set k = the k-th row at each ISO.
    let mut sets: Vec<Vec<&DarktableRow>> = Vec::new();
    let mut seen: Vec<(f64, usize)> = Vec::new();
    for r in &picked {
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
    let n_sets = sets.len();
    let describe_sets = || {
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
    };
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
                    describe_sets()
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
                    describe_sets()
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

fn quote_list(v: &[String]) -> String {
    v.iter()
        .map(|s| format!("'{s}'"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// The selection as profile noise entries, a and b verbatim; negative values are returned as
/// notes, and with `clamp_negative` written as 0.
pub fn to_noise(sel: &Selection, clamp_negative: bool) -> (Vec<NoiseAtIso>, Vec<String>) {
    const CH: [&str; 3] = ["R", "G", "B"];
    let mut negative = Vec::new();
    let mut noise = Vec::new();
    for r in &sel.rows {
        let mut fix = |name: &str, v: [f64; 3]| -> [f64; 3] {
            std::array::from_fn(|c| {
                if v[c] < 0.0 {
                    negative.push(format!(
                        "ISO {} {name}_{} = {:e} (line {})",
                        r.iso, CH[c], v[c], r.line
                    ));
                    if clamp_negative { 0.0 } else { v[c] }
                } else {
                    v[c]
                }
            })
        };
        let a = fix("a", r.a);
        let b = fix("b", r.b);
        noise.push(NoiseAtIso {
            iso: r.iso,
            a,
            b,
            a_stderr: None,
            b_stderr: None,
        });
    }
    (noise, negative)
}

/// Text for `provenance.noise`.
pub fn provenance(
    q: &Query,
    sel: &Selection,
    csv: &Path,
    negative: &[String],
    clamped: bool,
) -> String {
    let first = sel.rows.first();
    let last = sel.rows.last();
    let lines: Vec<usize> = sel.rows.iter().map(|r| r.line).collect();
    let mut s = format!(
        "darktable's noiseprofiles.json (darktable project, GPL-3+ data), flattened CSV {}: \
         maker '{}', model '{}', profile {}{}; {} ISO(s) {}–{}, CSV lines {}; a and b copied \
         verbatim (darktable's normalised convention σ² = a·x + b, x in [0, 1])",
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
    if !negative.is_empty() {
        let how = if clamped {
            "clamped to 0"
        } else {
            "kept verbatim (the realism operator clamps a·x + b at 0)"
        };
        s.push_str(&format!("; negative values {how}: {}", negative.join("; ")));
    }
    s
}
