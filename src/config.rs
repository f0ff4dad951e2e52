//! Typed TOML configs. Unknown keys are errors; messages name the file and the line.

use crate::error::{Error, Result};
use serde::de::DeserializeOwned;
use std::path::Path;

/// Read and parse a TOML file into `T`; errors carry the file name and toml's line/column.
pub fn load_toml<T: DeserializeOwned>(path: &Path) -> Result<T> {
    let text = crate::io::guard::read_text(path)?;
    parse_toml(&text, path)
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
