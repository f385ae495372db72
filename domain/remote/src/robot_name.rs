//! A robot's name on the link: the `<robot>` segment of every key. Lowercase letters, digits,
//! `-` and `_`, 1 to 32 bytes, so it is one key segment and can never hold a wildcard (`*`),
//! a separator (`/`) or Zenoh's reserved `@`, `$`, `?` and `#`.

use std::fmt;

use thiserror::Error;

/// Longest robot name, bytes.
pub const MAX_ROBOT_NAME_BYTES: usize = 32;

/// A validated robot name.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct RobotName(String);

/// Why a text is not a robot name.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[error(
    "robot name `{0}`: expected 1-{MAX_ROBOT_NAME_BYTES} lowercase letters, digits, `-` or `_`"
)]
pub struct RobotNameError(pub String);

impl RobotName {
    /// Checks `text`.
    pub fn parse(text: &str) -> Result<Self, RobotNameError> {
        let valid = !text.is_empty()
            && text.len() <= MAX_ROBOT_NAME_BYTES
            && text
                .bytes()
                .all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b == b'-' || b == b'_');
        if valid {
            Ok(Self(text.to_owned()))
        } else {
            Err(RobotNameError(text.to_owned()))
        }
    }

    /// `robot`: the name of a robot whose domain's name is not a valid one.
    pub fn fallback() -> Self {
        Self("robot".to_owned())
    }

    pub fn as_str(&self) -> &str {
        &self.0
    }
}

impl fmt::Display for RobotName {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::str::FromStr for RobotName {
    type Err = RobotNameError;

    fn from_str(text: &str) -> Result<Self, Self::Err> {
        Self::parse(text)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_one_plain_key_segment() {
        assert!(RobotName::parse("row7-left_2").is_ok());
        for bad in [
            "", "A", "a/b", "*", "**", "a*", "@x", "a$b", "a?b", "a#b", "a b",
        ] {
            assert!(RobotName::parse(bad).is_err(), "{bad}");
        }
        assert!(RobotName::parse(&"a".repeat(32)).is_ok());
        assert!(RobotName::parse(&"a".repeat(33)).is_err());
    }
}
