//! The library's one error type. Every variant about a file names the file.

use std::path::{Path, PathBuf};

#[derive(Debug, thiserror::Error)]
pub enum Error {
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The file exists but its content cannot be decoded (truncated, corrupt, wrong format).
    #[error("{}: cannot decode: {msg}", path.display())]
    Decode { path: PathBuf, msg: String },
    /// The file decodes but holds something we do not support (channels, bit depth, alpha).
    #[error("{}: unsupported: {msg}", path.display())]
    Unsupported { path: PathBuf, msg: String },
    /// Pixels that are NaN or infinite are never passed on silently.
    #[error("{}: {count} non-finite pixel values (NaN/Inf); first at x={x}, y={y}", path.display())]
    NonFinite {
        path: PathBuf,
        count: usize,
        x: usize,
        y: usize,
    },
    #[error("{}: cannot encode: {msg}", path.display())]
    Encode { path: PathBuf, msg: String },
    /// A TOML config or manifest that does not parse or validate.
    #[error("{}: {msg}", path.display())]
    Config { path: PathBuf, msg: String },
    /// A dataset folder that does not match the layout it claims or seems to have.
    #[error("{}: {msg}", path.display())]
    Layout { path: PathBuf, msg: String },
    /// An output folder locked by another running hdrsynth process.
    #[error(
        "{} is in use by another hdrsynth process ({holder}); wait for it to finish or choose \
         another output (lock: {})",
        path.display(),
        lock.display()
    )]
    InUse {
        path: PathBuf,
        /// The holder as its lock file names it ("pid unknown" when it names none).
        holder: String,
        lock: PathBuf,
    },
    /// A command-line flag (or the library option it sets) whose value cannot work: the flag
    /// as the user types it, then what is wrong with its value ("--max-gap 0 must be > 0").
    #[error("{flag} {msg}")]
    Flag { flag: String, msg: String },
    /// A named value (a profile's or config's key, an effect's parameter) that is out of range
    /// or inconsistent, where no file is read (a file's key: [`Error::Config`]).
    #[error("{key}: {msg}")]
    Key { key: String, msg: String },
    /// A sensor profile, by name, that cannot do what is asked of it (no colour calibration,
    /// no noise at an ISO, an effect that does not apply).
    #[error("profile '{name}': {msg}")]
    Profile { name: String, msg: String },
    /// A step of a longer pass (a set, a dataset) that failed, on one line ("what: cause"),
    /// the shape the dataset passes print; the cause stays typed for callers that match on it.
    #[error("{what}: {cause}")]
    Within { what: String, cause: Box<Error> },
    /// Parameters passed by code that break a function's contract (sizes that differ, an
    /// empty list): not a file, key or flag of the user's.
    #[error("{0}")]
    Invalid(String),
    /// A named step of a longer job (e.g. a quickstart stage) that failed; the cause is the
    /// source, so the message reads like `anyhow`'s context at the CLI edge.
    #[error("{what}")]
    Context {
        what: String,
        #[source]
        source: Box<dyn std::error::Error + Send + Sync>,
    },
}

pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    pub fn io(path: impl AsRef<Path>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.as_ref().to_path_buf(),
            source,
        }
    }
    pub fn decode(path: impl AsRef<Path>, msg: impl ToString) -> Self {
        Error::Decode {
            path: path.as_ref().to_path_buf(),
            msg: msg.to_string(),
        }
    }
    pub fn unsupported(path: impl AsRef<Path>, msg: impl ToString) -> Self {
        Error::Unsupported {
            path: path.as_ref().to_path_buf(),
            msg: msg.to_string(),
        }
    }
    pub fn encode(path: impl AsRef<Path>, msg: impl ToString) -> Self {
        Error::Encode {
            path: path.as_ref().to_path_buf(),
            msg: msg.to_string(),
        }
    }
    pub fn config(path: impl AsRef<Path>, msg: impl ToString) -> Self {
        Error::Config {
            path: path.as_ref().to_path_buf(),
            msg: msg.to_string(),
        }
    }
    pub fn context(
        what: impl ToString,
        source: impl Into<Box<dyn std::error::Error + Send + Sync>>,
    ) -> Self {
        Error::Context {
            what: what.to_string(),
            source: source.into(),
        }
    }
    /// `e` behind `what` on one line ("what: e"), for `map_err`: the message shape of the
    /// dataset passes. [`Error::context`] keeps the cause as the source instead (a chain, as
    /// `anyhow` prints it).
    pub fn within(what: String) -> impl FnOnce(Error) -> Error {
        move |e| Error::Within {
            what,
            cause: Box::new(e),
        }
    }
    pub fn flag(flag: impl ToString, msg: impl ToString) -> Self {
        Error::Flag {
            flag: flag.to_string(),
            msg: msg.to_string(),
        }
    }
    pub fn key(key: impl ToString, msg: impl ToString) -> Self {
        Error::Key {
            key: key.to_string(),
            msg: msg.to_string(),
        }
    }
    pub fn profile(name: impl ToString, msg: impl ToString) -> Self {
        Error::Profile {
            name: name.to_string(),
            msg: msg.to_string(),
        }
    }
    pub fn layout(path: impl AsRef<Path>, msg: impl ToString) -> Self {
        Error::Layout {
            path: path.as_ref().to_path_buf(),
            msg: msg.to_string(),
        }
    }
}
