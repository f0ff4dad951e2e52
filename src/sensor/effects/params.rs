//! Effect parameters: each effect reads its `[[effects]]` table into a
//! `#[derive(Deserialize)] #[serde(deny_unknown_fields)]` struct through [`parse`], whose
//! errors name the parameter (serde's own name only the type: "invalid type: string, expected
//! f64"). Unknown keys are reported first and the fields in declaration order, a missing one
//! where it falls, so the first fault found is the one the message names. [`float`], [`table`]
//! and [`seed_value`] write parameters (fits, reports, profiles).

use crate::error::Error;
use serde::Deserialize;
use serde::de::{
    self, DeserializeOwned, DeserializeSeed, Deserializer, IntoDeserializer, MapAccess, SeqAccess,
    Unexpected, Visitor,
};
use std::fmt;

/// The effect's parameters from its table (the `id` key already taken out); an error names
/// effect `id` and, in its message, the parameter.
pub fn parse<T: DeserializeOwned>(id: &str, p: &toml::Table) -> crate::error::Result<T> {
    T::deserialize(Table(p)).map_err(|e| fault(id, e))
}

/// A fault in effect `id`'s parameters: the key names the effect ("effect 'prnu'"), the
/// message the parameter, as profiles and the realism operator print them.
pub fn fault(id: &str, msg: impl ToString) -> Error {
    Error::key(format!("effect '{id}'"), msg)
}

// Writing parameters (fits, reports and profiles).

/// A pattern seed as a TOML value (62 bits, so it fits an i64).
pub fn seed_value(seed: u64) -> toml::Value {
    toml::Value::Integer((seed >> 2) as i64)
}

pub fn table(items: &[(&str, toml::Value)]) -> toml::Table {
    items
        .iter()
        .map(|(k, v)| (k.to_string(), v.clone()))
        .collect()
}

/// A float rounded to 4 significant digits, for params that go into reports and profiles.
pub fn float(v: f64) -> toml::Value {
    if v == 0.0 || !v.is_finite() {
        return toml::Value::Float(v);
    }
    let p = 10f64.powi(3 - v.abs().log10().floor() as i32);
    toml::Value::Float((v * p).round() / p)
}

/// A finite number (integer or float in the TOML).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Finite(pub f64);

impl<'de> Deserialize<'de> for Finite {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl Visitor<'_> for V {
            type Value = Finite;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a finite number")
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> Result<Finite, E> {
                Ok(Finite(v as f64))
            }
            fn visit_f64<E: de::Error>(self, v: f64) -> Result<Finite, E> {
                if v.is_finite() {
                    Ok(Finite(v))
                } else {
                    Err(E::invalid_value(Unexpected::Float(v), &self))
                }
            }
        }
        d.deserialize_any(V)
    }
}

/// A fixed-pattern seed (TOML integer ≥ 0).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Seed(pub u64);

impl<'de> Deserialize<'de> for Seed {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl Visitor<'_> for V {
            type Value = Seed;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("an integer ≥ 0")
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> Result<Seed, E> {
                u64::try_from(v)
                    .map(Seed)
                    .map_err(|_| E::invalid_value(Unexpected::Signed(v), &self))
            }
        }
        d.deserialize_any(V)
    }
}

/// A fixed offset pattern (column offsets, DSNU): σ in DN and the pattern's seed.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OffsetPattern {
    sigma_dn: Finite,
    seed: Seed,
}

impl OffsetPattern {
    /// (σ, seed) for effect `id`'s plan; σ must be ≥ 0.
    pub fn checked(self, id: &str) -> crate::error::Result<(f32, u64)> {
        let s = self.sigma_dn.0;
        if s < 0.0 {
            return Err(fault(id, format!("sigma_dn {s} must be ≥ 0")));
        }
        Ok((s as f32, self.seed.0))
    }
}

/// Three numbers > 0 (one per colour channel).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Triple(pub [f64; 3]);

impl<'de> Deserialize<'de> for Triple {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        #[derive(Deserialize)]
        #[serde(untagged)]
        enum Item {
            Number(f64),
            Other(de::IgnoredAny),
        }
        #[derive(Deserialize)]
        #[serde(untagged)]
        enum Shape {
            Array(Vec<Item>),
            Other(de::IgnoredAny),
        }
        let Shape::Array(items) = Shape::deserialize(d)? else {
            return Err(de::Error::custom("must be an array of 3 numbers"));
        };
        match items[..] {
            [Item::Number(a), Item::Number(b), Item::Number(c)]
                if [a, b, c].iter().all(|x| x.is_finite() && *x > 0.0) =>
            {
                Ok(Triple([a, b, c]))
            }
            _ => Err(de::Error::custom("must be 3 numbers > 0")),
        }
    }
}

/// What went wrong, before the parameter's key is known.
#[derive(Debug)]
enum Fault {
    /// A whole message.
    Message(String),
    /// A message to follow the parameter's key.
    Keyed(String),
    /// The value is not what the field expects (its description).
    Expected(String),
    /// The field is absent.
    Missing,
}

impl fmt::Display for Fault {
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        match self {
            Fault::Message(m) | Fault::Keyed(m) | Fault::Expected(m) => f.write_str(m),
            Fault::Missing => f.write_str("missing"),
        }
    }
}

impl std::error::Error for Fault {}

impl de::Error for Fault {
    fn custom<T: fmt::Display>(msg: T) -> Self {
        Fault::Keyed(msg.to_string())
    }
    fn invalid_type(unexp: Unexpected, exp: &dyn de::Expected) -> Self {
        // An absent field reaches its type as `none` (`Value::Missing`).
        if unexp == Unexpected::Option {
            Fault::Missing
        } else {
            Fault::Expected(exp.to_string())
        }
    }
    fn invalid_value(_: Unexpected, exp: &dyn de::Expected) -> Self {
        Fault::Expected(exp.to_string())
    }
    fn unknown_field(field: &str, expected: &'static [&'static str]) -> Self {
        Fault::Message(format!(
            "unknown parameter '{field}' (expected {})",
            expected.join(", ")
        ))
    }
}

fn missing(key: &str) -> String {
    if key == "seed" {
        "missing parameter 'seed' (fixed patterns derive from it)".into()
    } else {
        format!("missing parameter '{key}'")
    }
}

/// The effect's table, read as a struct.
struct Table<'a>(&'a toml::Table);

impl<'de> Deserializer<'de> for Table<'_> {
    type Error = Fault;

    fn deserialize_any<V: Visitor<'de>>(self, _: V) -> Result<V::Value, Fault> {
        Err(Fault::Message(
            "effect parameters are read as a struct".into(),
        ))
    }

    fn deserialize_struct<V: Visitor<'de>>(
        self,
        _: &'static str,
        fields: &'static [&'static str],
        visitor: V,
    ) -> Result<V::Value, Fault> {
        // Unknown keys first (`deny_unknown_fields` names them), then every field in order.
        let unknown = self.0.keys().filter(|k| !fields.contains(&k.as_str()));
        let keys: Vec<&str> = unknown
            .map(String::as_str)
            .chain(fields.iter().copied())
            .collect();
        visitor.visit_map(Entries {
            table: self.0,
            keys: keys.into_iter(),
            key: "",
        })
    }

    serde::forward_to_deserialize_any! {
        bool i8 i16 i32 i64 i128 u8 u16 u32 u64 u128 f32 f64 char str string bytes byte_buf
        option unit unit_struct newtype_struct seq tuple tuple_struct map enum identifier
        ignored_any
    }
}

struct Entries<'a> {
    table: &'a toml::Table,
    keys: std::vec::IntoIter<&'a str>,
    key: &'a str,
}

impl<'de> MapAccess<'de> for Entries<'_> {
    type Error = Fault;

    fn next_key_seed<K: DeserializeSeed<'de>>(
        &mut self,
        seed: K,
    ) -> Result<Option<K::Value>, Fault> {
        let Some(key) = self.keys.next() else {
            return Ok(None);
        };
        self.key = key;
        seed.deserialize(key.into_deserializer()).map(Some)
    }

    fn next_value_seed<V: DeserializeSeed<'de>>(&mut self, seed: V) -> Result<V::Value, Fault> {
        let key = self.key;
        let value = self.table.get(key);
        seed.deserialize(Value(value))
            .map_err(|e| match (e, value) {
                (Fault::Expected(what), Some(v)) => {
                    Fault::Message(format!("'{key}' must be {what}, got {v}"))
                }
                (Fault::Missing, _) | (Fault::Expected(_), None) => Fault::Message(missing(key)),
                (Fault::Keyed(m), _) => Fault::Message(format!("'{key}' {m}")),
                (Fault::Message(m), _) => Fault::Message(m),
            })
    }
}

/// One parameter's value; None when the key is absent (an `Option` field reads it as None).
struct Value<'a>(Option<&'a toml::Value>);

impl<'de> Deserializer<'de> for Value<'_> {
    type Error = Fault;

    fn deserialize_any<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Fault> {
        match self.0 {
            None => visitor.visit_none(),
            Some(toml::Value::Integer(i)) => visitor.visit_i64(*i),
            Some(toml::Value::Float(x)) => visitor.visit_f64(*x),
            Some(toml::Value::Boolean(b)) => visitor.visit_bool(*b),
            Some(toml::Value::String(s)) => visitor.visit_str(s),
            Some(toml::Value::Array(a)) => visitor.visit_seq(Items(a.iter())),
            // No parameter is a table or a date: to every field type, a wrong kind of value.
            Some(toml::Value::Table(_) | toml::Value::Datetime(_)) => visitor.visit_unit(),
        }
    }

    fn deserialize_option<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Fault> {
        match self.0 {
            None => visitor.visit_none(),
            Some(_) => visitor.visit_some(self),
        }
    }

    serde::forward_to_deserialize_any! {
        bool i8 i16 i32 i64 i128 u8 u16 u32 u64 u128 f32 f64 char str string bytes byte_buf
        unit unit_struct newtype_struct seq tuple tuple_struct map struct enum identifier
        ignored_any
    }
}

struct Items<'a>(std::slice::Iter<'a, toml::Value>);

impl<'de> SeqAccess<'de> for Items<'_> {
    type Error = Fault;

    fn next_element_seed<T: DeserializeSeed<'de>>(
        &mut self,
        seed: T,
    ) -> Result<Option<T::Value>, Fault> {
        self.0
            .next()
            .map(|v| seed.deserialize(Value(Some(v))))
            .transpose()
    }
}
