//! Typed TOML configs. Unknown keys are errors; messages name the file and the line.

use crate::error::{Error, Result};
use serde::de::DeserializeOwned;
use std::path::Path;

/// Read and parse a TOML file into `T`; errors carry the file name and toml's line/column.
pub fn load_toml<T: DeserializeOwned>(path: &Path) -> Result<T> {
    let text = crate::io::guard::read_text(path)?;
    parse_toml(&text, path)
}

/// [`load_toml`], then the value's rules (`check`, e.g. the struct's `validate`).
pub fn load_checked<T: DeserializeOwned>(
    path: &Path,
    check: impl FnOnce(&T) -> std::result::Result<(), KeyError>,
) -> Result<T> {
    let text = crate::io::guard::read_text(path)?;
    parse_checked(&text, path, check)
}

/// [`parse_toml`], then the value's rules: a broken one is an error naming the file, the line
/// of the key (for a key left at its default, of the table that would hold it) and the key,
/// `t.toml:12: key 'data.exposure': 0 is out of range (must be > 0)`.
pub fn parse_checked<T: DeserializeOwned>(
    text: &str,
    path: &Path,
    check: impl FnOnce(&T) -> std::result::Result<(), KeyError>,
) -> Result<T> {
    let value: T = parse_toml(text, path)?;
    check(&value).map_err(|e| e.at(path, Some(text)))?;
    Ok(value)
}

/// A parsed value that breaks its rule, with the key as the file spells it (`data.exposure`,
/// `noise[2].a[0]`). Each config struct's `validate` returns it with keys relative to the
/// struct; the struct holding it adds its own key ([`KeyError::within`]).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("key '{key}': {msg}")]
pub struct KeyError {
    pub key: String,
    pub msg: String,
}

impl KeyError {
    pub fn new(key: impl Into<String>, msg: impl Into<String>) -> KeyError {
        KeyError {
            key: key.into(),
            msg: msg.into(),
        }
    }

    /// The same error for the struct found under `prefix` (`optim` + `lr` → `optim.lr`).
    pub fn within(mut self, prefix: &str) -> KeyError {
        self.key = match self.key.starts_with('[') {
            true => format!("{prefix}{}", self.key),
            false => join_key(prefix, &self.key),
        };
        self
    }

    /// The error for the file `path`, with the key's line where `text` (the file's text)
    /// spells the key.
    pub fn at(self, path: &Path, text: Option<&str>) -> Error {
        match text.and_then(|t| key_line(t, &self.key)) {
            Some(line) => Error::config(format!("{}:{line}", path.display()), self.to_string()),
            None => Error::config(path, self.to_string()),
        }
    }
}

/// A rule broken in a value built by code rather than read from a file: an [`Error::Key`]
/// that prints as the key error does (`key 'data.exposure': …`).
impl From<KeyError> for Error {
    fn from(e: KeyError) -> Error {
        Error::key(format!("key '{}'", e.key), e.msg)
    }
}

/// The allowed values of a numeric key: a lower and an upper bound, each closed, open or
/// absent. Displayed as the message says it: `> 0`, `≥ 1`, `in [0, 1)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Range {
    lo: Bound,
    hi: Bound,
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Bound {
    Unbounded,
    Closed(f64),
    Open(f64),
}

impl Range {
    /// `> 0`.
    pub const POSITIVE: Range = Range::above(0.0);
    /// `≥ 0`.
    pub const NON_NEGATIVE: Range = Range::at_least(0.0);
    /// `[0, 1]`: a probability or a fraction.
    pub const UNIT: Range = Range::closed(0.0, 1.0);

    /// `≥ lo`.
    pub const fn at_least(lo: f64) -> Range {
        Range {
            lo: Bound::Closed(lo),
            hi: Bound::Unbounded,
        }
    }
    /// `> lo`.
    pub const fn above(lo: f64) -> Range {
        Range {
            lo: Bound::Open(lo),
            hi: Bound::Unbounded,
        }
    }
    /// `[lo, hi]`.
    pub const fn closed(lo: f64, hi: f64) -> Range {
        Range {
            lo: Bound::Closed(lo),
            hi: Bound::Closed(hi),
        }
    }
    /// `[lo, hi)`.
    pub const fn half_open(lo: f64, hi: f64) -> Range {
        Range {
            lo: Bound::Closed(lo),
            hi: Bound::Open(hi),
        }
    }
    /// `(lo, hi)`.
    pub const fn open(lo: f64, hi: f64) -> Range {
        Range {
            lo: Bound::Open(lo),
            hi: Bound::Open(hi),
        }
    }
    /// `(lo, hi]`.
    pub const fn left_open(lo: f64, hi: f64) -> Range {
        Range {
            lo: Bound::Open(lo),
            hi: Bound::Closed(hi),
        }
    }

    /// Whether `v` lies in the range (never for NaN).
    pub fn contains(self, v: f64) -> bool {
        let lo = match self.lo {
            Bound::Unbounded => !v.is_nan(),
            Bound::Closed(a) => v >= a,
            Bound::Open(a) => v > a,
        };
        let hi = match self.hi {
            Bound::Unbounded => !v.is_nan(),
            Bound::Closed(b) => v <= b,
            Bound::Open(b) => v < b,
        };
        lo && hi
    }
}

/// A bound as written: the shortest decimal of its f32 when it is one (a bound taken from an
/// f32 key prints 0.98, not 0.9800000190734863).
struct Shortest(f64);

impl std::fmt::Display for Shortest {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let v = self.0;
        if (v as f32) as f64 == v {
            write!(f, "{}", v as f32)
        } else {
            write!(f, "{v}")
        }
    }
}

impl std::fmt::Display for Range {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        use Bound::*;
        let (lo, hi) = (self.lo, self.hi);
        let n = Shortest;
        match (lo, hi) {
            (Unbounded, Unbounded) => f.write_str("a finite number"),
            (Closed(a), Unbounded) => write!(f, "≥ {}", n(a)),
            (Open(a), Unbounded) => write!(f, "> {}", n(a)),
            (Unbounded, Closed(b)) => write!(f, "≤ {}", n(b)),
            (Unbounded, Open(b)) => write!(f, "< {}", n(b)),
            (lo, hi) => {
                let (l, a) = match lo {
                    Closed(a) => ('[', a),
                    Open(a) => ('(', a),
                    Unbounded => unreachable!("bounded above and below"),
                };
                let (r, b) = match hi {
                    Closed(b) => (']', b),
                    Open(b) => (')', b),
                    Unbounded => unreachable!("bounded above and below"),
                };
                write!(f, "in {l}{}, {}{r}", n(a), n(b))
            }
        }
    }
}

/// A number a config holds, as its range rule sees it.
pub trait Number: Copy + std::fmt::Display {
    fn as_f64(self) -> f64;
}

macro_rules! number {
    ($($t:ty),*) => {$(
        impl Number for $t {
            fn as_f64(self) -> f64 {
                self as f64
            }
        }
    )*};
}
number!(f32, f64, u32, u64, usize, i64);

/// Error naming `key` unless `value` lies in `range`:
/// `key 'optim.lr': 0 is out of range (must be in (0, 1])`.
pub fn in_range(key: &str, value: impl Number, range: Range) -> std::result::Result<(), KeyError> {
    check(key, value, range, "")
}

/// [`in_range`] with what the bound protects in the parentheses (`… (must be ≥ 0: a negative
/// one grows the weights)`).
pub fn in_range_because(
    key: &str,
    value: impl Number,
    range: Range,
    why: &str,
) -> std::result::Result<(), KeyError> {
    check(key, value, range, why)
}

fn check(
    key: &str,
    value: impl Number,
    range: Range,
    why: &str,
) -> std::result::Result<(), KeyError> {
    if range.contains(value.as_f64()) {
        return Ok(());
    }
    let why = match why {
        "" => String::new(),
        w => format!(": {w}"),
    };
    Err(KeyError::new(
        key,
        format!("{value} is out of range (must be {range}{why})"),
    ))
}

/// [`in_range`] for every element of the array `key` (errors name `key[i]`).
pub fn each_in_range<T: Number>(
    key: &str,
    values: &[T],
    range: Range,
) -> std::result::Result<(), KeyError> {
    values
        .iter()
        .enumerate()
        .try_for_each(|(i, &v)| in_range(&format!("{key}[{i}]"), v, range))
}

/// The 1-based line of the value of the key path `key` (`a.b[2].c`) in the TOML `text`, or of
/// its deepest ancestor the text holds; None when not even its first part is there.
fn key_line(text: &str, key: &str) -> Option<usize> {
    use toml::de::DeValue;
    let doc = toml::de::DeTable::parse(text).ok()?;
    let mut parts = key_parts(key)?.into_iter();
    let Some(Part::Key(first)) = parts.next() else {
        return None;
    };
    let mut cur = doc
        .get_ref()
        .iter()
        .find(|(name, _)| name.get_ref().as_ref() == first)?
        .1;
    // As deep as the text spells the key: a key left at its default is placed at the table
    // that would hold it.
    for part in parts {
        let next = match (part, cur.get_ref()) {
            (Part::Key(k), DeValue::Table(t)) => t
                .iter()
                .find(|(name, _)| name.get_ref().as_ref() == k)
                .map(|(_, v)| v),
            (Part::Index(i), DeValue::Array(a)) => a.get(i),
            _ => None,
        };
        match next {
            Some(v) => cur = v,
            None => break,
        }
    }
    let start = cur.span().start.min(text.len());
    Some(text[..start].matches('\n').count() + 1)
}

enum Part<'a> {
    Key(&'a str),
    Index(usize),
}

/// `a.b[2][0].c` → a, b, 2, 0, c.
fn key_parts(key: &str) -> Option<Vec<Part<'_>>> {
    let mut out = Vec::new();
    for seg in key.split('.') {
        let (name, mut rest) = seg.split_once('[').unwrap_or((seg, ""));
        if !name.is_empty() {
            out.push(Part::Key(name));
        }
        while !rest.is_empty() {
            let (i, after) = rest.split_once(']')?;
            out.push(Part::Index(i.parse().ok()?));
            rest = after.strip_prefix('[').unwrap_or(after);
        }
    }
    Some(out)
}

/// Parse TOML text into `T`; errors name `path`, the line and, where the text has one there,
/// the key (`file:line: key 'run.steps': invalid type …`). Every float in the text must be
/// finite: TOML spells NaN and infinities (`nan`, `inf`) and no setting of the tool means
/// one, so they are refused here, the one place every config, profile and manifest passes.
pub fn parse_toml<T: DeserializeOwned>(text: &str, path: &Path) -> Result<T> {
    let at = |offset: usize| {
        let line = text[..offset.min(text.len())].matches('\n').count() + 1;
        format!("{}:{line}", path.display())
    };
    // The spanned document: None when the text does not parse, and toml's own error below
    // then says why.
    let doc = toml::de::DeTable::parse(text).ok();
    if let Some(doc) = &doc
        && let Some((key, span, raw)) = first_non_finite(doc.get_ref(), "")
    {
        return Err(Error::config(
            at(span.start),
            format!("key '{key}': {raw} is not a finite number (NaN and infinities are refused)"),
        ));
    }
    toml::from_str(text).map_err(|e| {
        let msg = e.message().trim_end().to_string();
        let Some(span) = e.span() else {
            return Error::config(path, msg);
        };
        if msg == "duplicate key"
            && let Some(twice) = duplicate_key(text, span.start)
        {
            return Error::config(at(span.start), twice);
        }
        let key = doc
            .as_ref()
            .and_then(|d| key_of_error(d.get_ref(), &span, &msg));
        match key {
            Some(key) if !msg.contains(&format!("`{}`", last_part(&key))) => {
                Error::config(at(span.start), format!("key '{key}': {msg}"))
            }
            _ => Error::config(at(span.start), msg),
        }
    })
}

/// The dotted keys whose values differ between two TOML documents `old` and `new` (at most 5,
/// then a count), each as "key: old → new" ("(absent)" for a missing side).
pub fn differing_keys(old: &str, new: &str) -> Vec<String> {
    fn flatten(
        prefix: &str,
        t: &toml::Table,
        out: &mut std::collections::BTreeMap<String, String>,
    ) {
        for (k, v) in t {
            let key = if prefix.is_empty() {
                k.clone()
            } else {
                format!("{prefix}.{k}")
            };
            match v {
                toml::Value::Table(inner) => flatten(&key, inner, out),
                other => {
                    out.insert(key, other.to_string());
                }
            }
        }
    }
    let table = |text: &str| {
        let mut m = std::collections::BTreeMap::new();
        if let Ok(t) = text.parse::<toml::Table>() {
            flatten("", &t, &mut m);
        }
        m
    };
    let (a, b) = (table(old), table(new));
    let absent = "(absent)".to_string();
    let mut keys: Vec<&String> = a.keys().chain(b.keys()).collect();
    keys.sort();
    keys.dedup();
    let diffs: Vec<String> = keys
        .into_iter()
        .filter(|k| a.get(*k) != b.get(*k))
        .map(|k| {
            format!(
                "{k}: {} → {}",
                a.get(k).unwrap_or(&absent),
                b.get(k).unwrap_or(&absent)
            )
        })
        .collect();
    let n = diffs.len();
    let mut shown: Vec<String> = diffs.into_iter().take(5).collect();
    if n > 5 {
        shown.push(format!("and {} more", n - 5));
    }
    shown
}

/// toml's "duplicate key" at byte `offset`, said with the key and both lines: "key 'run.steps'
/// is given twice (lines 3 and 4); give it once". `None` when the line is not `key = value`.
fn duplicate_key(text: &str, offset: usize) -> Option<String> {
    let lines: Vec<&str> = text.lines().collect();
    let n = text[..offset.min(text.len())].matches('\n').count();
    let key_of = |l: &str| l.split_once('=').map(|(k, _)| k.trim().to_string());
    let key = key_of(lines.get(n)?)?;
    // The table the line is in, and the key's first line within it.
    let start = (0..n)
        .rev()
        .find(|&i| lines[i].trim_start().starts_with('['))
        .map_or(0, |i| i + 1);
    let table = start
        .checked_sub(1)
        .map(|i| lines[i].trim().trim_matches(['[', ']']).trim().to_string());
    let first = (start..n).find(|&i| key_of(lines[i]).as_deref() == Some(key.as_str()))?;
    let full = match table {
        Some(t) if !t.is_empty() => format!("{t}.{key}"),
        _ => key,
    };
    Some(format!(
        "key '{full}' is given twice (lines {} and {}); give it once",
        first + 1,
        n + 1
    ))
}

/// The key a deserialisation error is about: the deepest key whose value spans the error's
/// span. Values buffered by serde (an internally tagged table such as `[model]`) report their
/// errors on the whole table; then the one scalar in it that the message quotes, if exactly
/// one, is the key.
fn key_of_error(
    doc: &toml::de::DeTable,
    span: &std::ops::Range<usize>,
    msg: &str,
) -> Option<String> {
    let (key, value) = key_at(doc, "", span)?;
    let Some(quoted) = quoted_value(msg) else {
        return Some(key);
    };
    let mut hits = Vec::new();
    scalars_equal(value, &key, &quoted, &mut hits);
    match hits.as_slice() {
        [one] => Some(one.clone()),
        _ => Some(key),
    }
}

/// The value a serde message quotes: "integer `-1`", "string \"two\"", "floating point
/// `1.5`", "boolean `true`".
fn quoted_value(msg: &str) -> Option<String> {
    for (open, close) in [
        ("integer `", '`'),
        ("floating point `", '`'),
        ("boolean `", '`'),
        ("string \"", '"'),
    ] {
        if let Some(i) = msg.find(open) {
            let rest = &msg[i + open.len()..];
            return rest.find(close).map(|j| rest[..j].to_string());
        }
    }
    None
}

fn scalars_equal(v: &Spanned<toml::de::DeValue>, key: &str, text: &str, out: &mut Vec<String>) {
    use toml::de::DeValue;
    match v.get_ref() {
        DeValue::Integer(i) if i.as_str().replace('_', "") == text => out.push(key.to_string()),
        DeValue::Float(f) if f.as_str().replace('_', "") == text => out.push(key.to_string()),
        DeValue::Boolean(b) if b.to_string() == text => out.push(key.to_string()),
        DeValue::String(s) if s.as_ref() == text => out.push(key.to_string()),
        DeValue::Table(t) => {
            for (k, x) in t.iter() {
                scalars_equal(x, &join_key(key, k.get_ref()), text, out);
            }
        }
        DeValue::Array(a) => {
            for (i, x) in a.iter().enumerate() {
                scalars_equal(x, &format!("{key}[{i}]"), text, out);
            }
        }
        _ => {}
    }
}

type Spanned<T> = toml::Spanned<T>;

fn join_key(prefix: &str, key: &str) -> String {
    if prefix.is_empty() {
        key.to_string()
    } else {
        format!("{prefix}.{key}")
    }
}

/// The last dotted part of a key path, without an array index.
fn last_part(key: &str) -> &str {
    let last = key.rsplit('.').next().unwrap_or(key);
    last.split('[').next().unwrap_or(last)
}

/// The first float of `table` (depth first, in key order) that is NaN or infinite: its key
/// path, span and text.
fn first_non_finite(
    table: &toml::de::DeTable,
    prefix: &str,
) -> Option<(String, std::ops::Range<usize>, String)> {
    table
        .iter()
        .find_map(|(k, v)| non_finite_in(v, &join_key(prefix, k.get_ref())))
}

fn non_finite_in(
    v: &Spanned<toml::de::DeValue>,
    key: &str,
) -> Option<(String, std::ops::Range<usize>, String)> {
    use toml::de::DeValue;
    match v.get_ref() {
        DeValue::Float(f) => {
            let raw = f.as_str();
            let bare = raw.replace('_', "");
            let word = bare.trim_start_matches(['+', '-']);
            let finite = !word.starts_with("nan")
                && !word.starts_with("inf")
                && bare.parse::<f64>().is_ok_and(f64::is_finite);
            (!finite).then(|| (key.to_string(), v.span(), raw.to_string()))
        }
        DeValue::Table(t) => first_non_finite(t, key),
        DeValue::Array(a) => a
            .iter()
            .enumerate()
            .find_map(|(i, x)| non_finite_in(x, &format!("{key}[{i}]"))),
        _ => None,
    }
}

/// The deepest key whose key or value span holds all of `span`, and its value.
fn key_at<'a, 'i>(
    table: &'a toml::de::DeTable<'i>,
    prefix: &str,
    span: &std::ops::Range<usize>,
) -> Option<(String, &'a Spanned<toml::de::DeValue<'i>>)> {
    table.iter().find_map(|(k, v)| {
        let key = join_key(prefix, k.get_ref());
        if holds(&k.span(), span) {
            return Some((key, v));
        }
        key_in(v, key, span)
    })
}

fn key_in<'a, 'i>(
    v: &'a Spanned<toml::de::DeValue<'i>>,
    key: String,
    span: &std::ops::Range<usize>,
) -> Option<(String, &'a Spanned<toml::de::DeValue<'i>>)> {
    use toml::de::DeValue;
    // Children first, whatever the parent's span: a table's sub-tables may be written
    // elsewhere in the file (`[data.metering]` after other tables).
    let deeper = match v.get_ref() {
        DeValue::Table(t) => key_at(t, &key, span),
        DeValue::Array(a) => a
            .iter()
            .enumerate()
            .find_map(|(i, x)| key_in(x, format!("{key}[{i}]"), span)),
        _ => None,
    };
    deeper.or_else(|| holds(&v.span(), span).then_some((key, v)))
}

fn holds(outer: &std::ops::Range<usize>, inner: &std::ops::Range<usize>) -> bool {
    outer.start <= inner.start && inner.end <= outer.end
}

/// Merge `over` into `base`: tables merge key by key (recursively), anything else replaces.
/// How an ablation cell's settings are laid over its base training config.
pub fn merge_tables(base: &mut toml::Table, over: &toml::Table) {
    for (k, v) in over {
        match (base.get_mut(k), v) {
            (Some(toml::Value::Table(b)), toml::Value::Table(o)) => merge_tables(b, o),
            _ => {
                base.insert(k.clone(), v.clone());
            }
        }
    }
}

/// The field names a derived `Deserialize` of a struct declares (the keys its table accepts),
/// read from the derive itself so that no second list has to be kept in step with the struct.
pub fn struct_fields<'de, T: serde::Deserialize<'de>>() -> &'static [&'static str] {
    use serde::de::{self, Visitor};
    /// A deserializer that only records the fields `deserialize_struct` is asked for.
    struct Probe<'a>(&'a mut &'static [&'static str]);
    impl<'de> de::Deserializer<'de> for Probe<'_> {
        type Error = de::value::Error;
        fn deserialize_any<V: Visitor<'de>>(
            self,
            _: V,
        ) -> std::result::Result<V::Value, Self::Error> {
            Err(de::Error::custom("not a struct"))
        }
        fn deserialize_struct<V: Visitor<'de>>(
            self,
            _: &'static str,
            fields: &'static [&'static str],
            _: V,
        ) -> std::result::Result<V::Value, Self::Error> {
            *self.0 = fields;
            Err(de::Error::custom("fields read"))
        }
        serde::forward_to_deserialize_any! {
            bool i8 i16 i32 i64 i128 u8 u16 u32 u64 u128 f32 f64 char str string bytes byte_buf
            option unit unit_struct newtype_struct seq tuple tuple_struct map enum identifier
            ignored_any
        }
    }
    let mut fields: &'static [&'static str] = &[];
    let _ = T::deserialize(Probe(&mut fields));
    fields
}

#[cfg(test)]
mod tests {
    use super::*;

    const TEXT: &str = "seed = 1\n\n[data]\nexposure = 0.5\nisos = [\n  100,\n  200,\n]\n\n\
                        [[noise]]\niso = 100.0\na = [1, 2, 3]\n\n[[noise]]\niso = 200.0\n";

    #[test]
    fn a_key_path_is_found_at_the_line_of_its_value() {
        for (key, line) in [
            ("seed", Some(1)),
            ("data.exposure", Some(4)),
            ("data.isos[1]", Some(7)),
            ("noise[0].a[2]", Some(12)),
            ("noise[1].iso", Some(15)),
            // Not in the text: the deepest ancestor that is, a table at its header.
            ("noise[1].a[0]", Some(14)),
            ("data.metering.mid_grey", Some(3)),
            ("optim.lr", None),
        ] {
            assert_eq!(key_line(TEXT, key), line, "{key}");
        }
    }

    #[test]
    fn ranges_test_and_print_their_bounds() {
        let cases = [
            (Range::POSITIVE, "> 0", [(0.0, false), (1e-300, true)]),
            (Range::at_least(1.0), "≥ 1", [(0.5, false), (1.0, true)]),
            (
                Range::half_open(0.0, 1.0),
                "in [0, 1)",
                [(1.0, false), (0.0, true)],
            ),
            (
                Range::left_open(0.0, 1.0),
                "in (0, 1]",
                [(0.0, false), (1.0, true)],
            ),
            (
                Range::open(0.0, 0.98f32 as f64),
                "in (0, 0.98)",
                [(0.98f32 as f64, false), (0.5, true)],
            ),
            (
                Range::closed(-1.0, 1e-3),
                "in [-1, 0.001]",
                [(0.0011, false), (-1.0, true)],
            ),
        ];
        for (r, text, probes) in cases {
            assert_eq!(r.to_string(), text);
            for (v, inside) in probes {
                assert_eq!(r.contains(v), inside, "{text} {v}");
            }
            assert!(!r.contains(f64::NAN), "{text}");
        }
    }

    #[test]
    fn a_broken_rule_names_file_line_key_and_range() {
        let e = in_range("exposure", 0.0f64, Range::POSITIVE)
            .unwrap_err()
            .within("data");
        assert_eq!(e.key, "data.exposure");
        assert_eq!(
            e.at(Path::new("t.toml"), Some(TEXT)).to_string(),
            "t.toml:4: key 'data.exposure': 0 is out of range (must be > 0)"
        );
        let e = in_range_because("lr", 2.0f64, Range::left_open(0.0, 1.0), "why").unwrap_err();
        assert_eq!(
            e.to_string(),
            "key 'lr': 2 is out of range (must be in (0, 1]: why)"
        );
        let e = each_in_range("isos", &[100.0, -1.0], Range::POSITIVE).unwrap_err();
        assert_eq!(e.key, "isos[1]");
        assert_eq!(
            e.at(Path::new("t.toml"), None).to_string(),
            "t.toml: key 'isos[1]': -1 is out of range (must be > 0)"
        );
    }
}
