//! Reading a typed TOML settings file: one place for the file and parse errors every process's
//! `--config` shares. The types carry `#[serde(deny_unknown_fields)]`, so toml's message names
//! the line, column and key of an unknown or mistyped key; range checks stay with each type.

use serde::de::DeserializeOwned;
use std::path::{Path, PathBuf};

/// A settings file that cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum ConfigFileError {
    /// The file could not be read.
    #[error("cannot read {what} {path}: {source}")]
    Read {
        /// What the file holds ("arm settings", "perception config", ...).
        what: &'static str,
        /// The file.
        path: PathBuf,
        /// Why it could not be read.
        source: std::io::Error,
    },
    /// Not valid TOML, an unknown key or a wrongly typed value.
    #[error("{what} {origin}: {message}")]
    Parse {
        /// What the file holds.
        what: &'static str,
        /// The file (or other origin) of the text.
        origin: String,
        /// toml's message: line, column, key.
        message: String,
    },
}

/// Reads and parses the TOML file at `path`; `what` names its content in errors.
pub fn read_toml<T: DeserializeOwned>(
    path: &Path,
    what: &'static str,
) -> Result<T, ConfigFileError> {
    let text = std::fs::read_to_string(path).map_err(|source| ConfigFileError::Read {
        what,
        path: path.to_owned(),
        source,
    })?;
    parse_toml(&text, &path.display().to_string(), what)
}

/// Parses TOML text; `origin` and `what` name it in errors.
pub fn parse_toml<T: DeserializeOwned>(
    text: &str,
    origin: &str,
    what: &'static str,
) -> Result<T, ConfigFileError> {
    toml::from_str(text).map_err(|error| ConfigFileError::Parse {
        what,
        origin: origin.to_owned(),
        message: error.to_string(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, PartialEq, serde::Deserialize)]
    #[serde(deny_unknown_fields)]
    struct Settings {
        period_us: u64,
    }

    #[test]
    fn errors_name_the_file_and_the_key() {
        let parsed: Settings =
            parse_toml("period_us = 5000", "a.toml", "test settings").expect("ok");
        assert_eq!(parsed, Settings { period_us: 5000 });
        let message = parse_toml::<Settings>("period = 1", "b.toml", "test settings")
            .expect_err("unknown key")
            .to_string();
        assert!(
            message.contains("b.toml") && message.contains("period"),
            "{message}"
        );
        let missing = Path::new("/nonexistent/harvest.toml");
        let message = read_toml::<Settings>(missing, "test settings")
            .expect_err("missing file")
            .to_string();
        assert!(message.contains("/nonexistent/harvest.toml"), "{message}");
    }
}
