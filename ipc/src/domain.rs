//! Domains: every iceoryx2 resource of a stack is namespaced by its domain, so two stacks on
//! one host never see each other.
//!
//! The domain becomes the iceoryx2 `global.prefix` (`hv_<domain>_`): shared-memory segments,
//! service and node files all carry it. iceoryx2 has no access control: the prefix is our
//! separation, not a security boundary.

use iceoryx2::config::Config;
use iceoryx2::prelude::{FileName, SemanticString};

/// Environment variable read when no `--domain` is given.
pub const DOMAIN_ENV: &str = "HARVEST_DOMAIN";
/// Domain used when neither flag nor environment names one.
pub const DEFAULT_DOMAIN: &str = "default";
const MAX_DOMAIN_LEN: usize = 24;

/// A validated domain name: 1-24 characters of `[a-z0-9_-]`.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct Domain(String);

/// A domain name that cannot be used.
#[derive(Debug, thiserror::Error)]
#[error(
    "invalid domain {name:?}: use 1-{MAX_DOMAIN_LEN} characters of lowercase letters, digits, '_' or '-'"
)]
pub struct InvalidDomain {
    /// The name that was refused.
    pub name: String,
}

impl Domain {
    /// The domain `name`, if it is 1 to `MAX_DOMAIN_LEN` lowercase letters, digits, `_` or `-`.
    pub fn new(name: &str) -> Result<Self, InvalidDomain> {
        let valid = !name.is_empty()
            && name.len() <= MAX_DOMAIN_LEN
            && name
                .bytes()
                .all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b == b'_' || b == b'-');
        if valid {
            Ok(Self(name.to_owned()))
        } else {
            Err(InvalidDomain {
                name: name.to_owned(),
            })
        }
    }

    /// The flag's value, else `$HARVEST_DOMAIN`, else `default`.
    pub fn from_flag_or_env(flag: Option<&str>) -> Result<Self, InvalidDomain> {
        match flag {
            Some(name) => Self::new(name),
            None => match std::env::var(DOMAIN_ENV) {
                Ok(name) if !name.is_empty() => Self::new(&name),
                _ => Self::new(DEFAULT_DOMAIN),
            },
        }
    }

    /// A domain no other caller on this host uses at the same time: `tag` (its lowercase
    /// letters and digits, at most 6) followed by the process id, a per-process counter and
    /// the clock's nanoseconds, cut to the 24-character limit. For tests and benchmarks that
    /// start their own stack beside any running one.
    pub fn unique(tag: &str) -> Self {
        static COUNTER: std::sync::atomic::AtomicU32 = std::sync::atomic::AtomicU32::new(0);
        let tag: String = tag
            .chars()
            .filter(|c| c.is_ascii_lowercase() || c.is_ascii_digit())
            .take(6)
            .collect();
        let nanos = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |elapsed| elapsed.subsec_nanos());
        let counter = COUNTER.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let mut name = format!(
            "{tag}-{}-{counter}-{:x}",
            std::process::id() % 1_000_000,
            nanos % 0xffff
        );
        name.truncate(MAX_DOMAIN_LEN);
        Self(name)
    }

    /// The domain name (the iceoryx2 file prefix).
    pub fn name(&self) -> &str {
        &self.0
    }

    /// Prefix of every iceoryx2 file of this domain.
    pub fn file_prefix(&self) -> String {
        format!("hv_{}_", self.0)
    }

    /// The iceoryx2 configuration of this domain (no config file is read: the stack's
    /// settings are all here, so behaviour does not depend on the working directory).
    pub fn iceoryx2_config(&self) -> Config {
        let mut config = Config::default();
        // The name was validated to be a plain file-name fragment of bounded length.
        if let Ok(prefix) = FileName::new(self.file_prefix().as_bytes()) {
            config.global.prefix = prefix;
        }
        config
    }
}

impl std::fmt::Display for Domain {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn validates_names() {
        assert!(Domain::new("robot-1_test").is_ok());
        assert!(Domain::new("").is_err());
        assert!(Domain::new("Upper").is_err());
        assert!(Domain::new("a/b").is_err());
        assert!(Domain::new(&"x".repeat(25)).is_err());
        let domain = Domain::new("abc").expect("valid");
        assert_eq!(
            domain.iceoryx2_config().global.prefix.as_bytes(),
            b"hv_abc_"
        );
    }

    #[test]
    fn unique_domains_are_valid_and_distinct() {
        let first = Domain::unique("Tag With Spaces And/Slashes");
        let second = Domain::unique("Tag With Spaces And/Slashes");
        assert_ne!(first, second);
        for domain in [first, second] {
            assert!(domain.name().starts_with("agithp-"), "{domain}");
            assert!(Domain::new(domain.name()).is_ok(), "{domain}");
        }
    }
}
