//! The control token: `harvest up` makes a random one at start, prints it, writes it to a file
//! only its user can read (mode 0600 in a 0700 directory) and hands it to the executive in
//! [`CONTROL_TOKEN_ENV`]. A client that controls (`harvest ctl`, the console's control panel)
//! sends it with every command; watching needs none.
//!
//! Where the file is ([`token_path`]): `$XDG_RUNTIME_DIR/harvest/<domain>.token`, else
//! `/tmp/harvest-<uid>/<domain>.token`.

use std::io::{Read, Write};
use std::os::unix::fs::{DirBuilderExt, MetadataExt, OpenOptionsExt, PermissionsExt};
use std::path::{Path, PathBuf};

use thiserror::Error;

/// Environment variable through which the supervisor hands the token to the executive.
pub const CONTROL_TOKEN_ENV: &str = "HARVEST_CONTROL_TOKEN";
/// Random bytes in a token (printed as twice as many hexadecimal digits).
const TOKEN_BYTES: usize = 16;

/// Problems with a token or its file.
#[derive(Debug, Error)]
pub enum TokenError {
    /// The system's random source could not be read.
    #[error("reading /dev/urandom for a control token: {0}")]
    Random(std::io::Error),
    /// The token file or its directory could not be written.
    #[error("writing the control token file {path}: {source}")]
    Write {
        path: PathBuf,
        source: std::io::Error,
    },
    /// The token file could not be read.
    #[error(
        "reading the control token file {path}: {source} (is `harvest up` running in this domain?)"
    )]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    /// The text is not a token.
    #[error("{origin}: not a control token (expected {TOKEN_BYTES}x2 hexadecimal digits)")]
    Malformed { origin: String },
    /// Others may read the token file.
    #[error("{path}: readable by others (mode {mode:o}); expected 600")]
    Exposed { path: PathBuf, mode: u32 },
}

/// A control token (lowercase hexadecimal).
#[derive(Clone, PartialEq, Eq)]
pub struct ControlToken(String);

impl std::fmt::Debug for ControlToken {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        // Never in logs.
        f.write_str("ControlToken(..)")
    }
}

/// `N` bytes from the system's random source.
pub fn random_bytes<const N: usize>() -> Result<[u8; N], TokenError> {
    let mut bytes = [0u8; N];
    std::fs::File::open("/dev/urandom")
        .and_then(|mut source| source.read_exact(&mut bytes))
        .map_err(TokenError::Random)?;
    Ok(bytes)
}

/// A random non-zero session id for a client.
pub fn new_session_id() -> Result<u64, TokenError> {
    Ok(u64::from_le_bytes(random_bytes::<8>()?).max(1))
}

impl ControlToken {
    /// A new random token.
    pub fn generate() -> Result<Self, TokenError> {
        let bytes = random_bytes::<TOKEN_BYTES>()?;
        Ok(Self(bytes.iter().map(|b| format!("{b:02x}")).collect()))
    }

    /// Parses a token (surrounding white space ignored); `origin` names where it came from.
    pub fn parse(text: &str, origin: &str) -> Result<Self, TokenError> {
        let text = text.trim();
        let valid = text.len() == TOKEN_BYTES * 2
            && text
                .bytes()
                .all(|b| b.is_ascii_digit() || (b'a'..=b'f').contains(&b));
        if valid {
            Ok(Self(text.to_owned()))
        } else {
            Err(TokenError::Malformed {
                origin: origin.to_owned(),
            })
        }
    }

    pub fn as_str(&self) -> &str {
        &self.0
    }

    /// Whether `candidate` is this token, in time independent of where they differ.
    pub fn matches(&self, candidate: &str) -> bool {
        let (a, b) = (self.0.as_bytes(), candidate.as_bytes());
        let mut difference = u8::from(a.len() != b.len());
        for (x, y) in a.iter().zip(b.iter().chain(std::iter::repeat(&0))) {
            difference |= x ^ y;
        }
        difference == 0
    }
}

/// The token file of `domain` (module docs).
pub fn token_path(domain: &str) -> PathBuf {
    let directory = match std::env::var_os("XDG_RUNTIME_DIR") {
        Some(runtime) if !runtime.is_empty() => PathBuf::from(runtime).join("harvest"),
        _ => {
            let uid = std::fs::metadata("/proc/self").map_or(0, |meta| meta.uid());
            std::env::temp_dir().join(format!("harvest-{uid}"))
        }
    };
    directory.join(format!("{domain}.token"))
}

/// Writes `token` to `path` (directory 0700, file 0600, replaced if present).
pub fn write_token_file(path: &Path, token: &ControlToken) -> Result<(), TokenError> {
    let error = |source| TokenError::Write {
        path: path.to_owned(),
        source,
    };
    if let Some(directory) = path.parent() {
        std::fs::DirBuilder::new()
            .recursive(true)
            .mode(0o700)
            .create(directory)
            .map_err(error)?;
    }
    // A file left by another run may have other permissions: replace it.
    match std::fs::remove_file(path) {
        Ok(()) => {}
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
        Err(e) => return Err(error(e)),
    }
    let mut file = std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .mode(0o600)
        .open(path)
        .map_err(error)?;
    writeln!(file, "{}", token.as_str()).map_err(error)?;
    Ok(())
}

/// Reads the token at `path`, refusing a file others may read.
pub fn read_token_file(path: &Path) -> Result<ControlToken, TokenError> {
    let error = |source| TokenError::Read {
        path: path.to_owned(),
        source,
    };
    let meta = std::fs::metadata(path).map_err(error)?;
    let mode = meta.permissions().mode() & 0o777;
    if mode & 0o077 != 0 {
        return Err(TokenError::Exposed {
            path: path.to_owned(),
            mode,
        });
    }
    let text = std::fs::read_to_string(path).map_err(error)?;
    ControlToken::parse(&text, &path.display().to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tokens_are_random_hex_and_match_only_themselves() {
        let a = ControlToken::generate().expect("token");
        let b = ControlToken::generate().expect("token");
        assert_ne!(a, b);
        assert_eq!(a.as_str().len(), 32);
        assert!(a.matches(a.as_str()));
        assert!(!a.matches(b.as_str()));
        assert!(!a.matches(""));
        assert!(!a.matches(&a.as_str()[..31]));
        assert!(!a.matches(&format!("{}0", a.as_str())));
        assert_eq!(format!("{a:?}"), "ControlToken(..)");
        assert!(ControlToken::parse("xyz", "test").is_err());
        assert_eq!(
            ControlToken::parse(&format!(" {}\n", a.as_str()), "test").expect("parse"),
            a
        );
    }

    #[test]
    fn the_file_is_private_and_reads_back() {
        let directory = std::env::temp_dir().join(format!(
            "harvest-token-test-{}",
            new_session_id().expect("id")
        ));
        let path = directory.join("sub").join("d.token");
        let token = ControlToken::generate().expect("token");
        write_token_file(&path, &token).expect("write");
        let mode = std::fs::metadata(&path).expect("meta").permissions().mode() & 0o777;
        assert_eq!(mode, 0o600);
        let dir_mode = std::fs::metadata(path.parent().expect("parent"))
            .expect("meta")
            .permissions()
            .mode()
            & 0o777;
        assert_eq!(dir_mode, 0o700);
        assert_eq!(read_token_file(&path).expect("read"), token);
        // Rewritten on the next start.
        let next = ControlToken::generate().expect("token");
        write_token_file(&path, &next).expect("rewrite");
        assert_eq!(read_token_file(&path).expect("read"), next);
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o644)).expect("chmod");
        assert!(matches!(
            read_token_file(&path),
            Err(TokenError::Exposed { .. })
        ));
        let _ = std::fs::remove_dir_all(&directory);
    }

    #[test]
    fn the_path_is_per_domain() {
        assert!(token_path("abc").ends_with("abc.token"));
        assert_ne!(token_path("a"), token_path("b"));
    }
}
