//! The mode kept across a restart of the executive. The executive writes the mode and the
//! enabled arms beside the token file on every change; a restarted executive of the same
//! `harvest up` run (same token) reads them back, so a crash neither resumes a paused harvest
//! nor forgets a disabled arm. A file of another run (another token) is ignored. The file holds
//! a fingerprint of the token, never the token.

use std::path::{Path, PathBuf};

use harvest_ipc::payloads::OperatorModeCode;

use crate::token::ControlToken;

/// The mode file beside a token file (`<domain>.mode`).
pub fn mode_path(token_path: &Path) -> PathBuf {
    token_path.with_extension("mode")
}

/// FNV-1a of the token: tells runs apart without revealing the token.
fn fingerprint(token: &ControlToken) -> u64 {
    token
        .as_str()
        .bytes()
        .fold(0xcbf2_9ce4_8422_2325, |hash, byte| {
            (hash ^ u64::from(byte)).wrapping_mul(0x0100_0000_01b3)
        })
}

/// Writes the mode (errors are the caller's to log: losing the file only loses the restore).
pub fn save_mode(
    path: &Path,
    token: &ControlToken,
    mode: OperatorModeCode,
    arms_enabled: [bool; 2],
) -> std::io::Result<()> {
    let text = format!(
        "{:016x} {} {} {}\n",
        fingerprint(token),
        mode as u8,
        u8::from(arms_enabled[0]),
        u8::from(arms_enabled[1])
    );
    let temporary = path.with_extension("mode.tmp");
    std::fs::write(&temporary, text)?;
    std::fs::rename(&temporary, path)
}

/// The mode saved by this run (same token), if any.
pub fn load_mode(path: &Path, token: &ControlToken) -> Option<(OperatorModeCode, [bool; 2])> {
    let text = std::fs::read_to_string(path).ok()?;
    let mut words = text.split_whitespace();
    let saved = u64::from_str_radix(words.next()?, 16).ok()?;
    if saved != fingerprint(token) {
        return None;
    }
    let mode = OperatorModeCode::from_code(words.next()?.parse().ok()?)?;
    let arm1 = words.next()? == "1";
    let arm2 = words.next()? == "1";
    Some((mode, [arm1, arm2]))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_mode_comes_back_for_the_same_run_only() {
        let path = std::env::temp_dir().join(format!(
            "harvest-mode-test-{}.mode",
            crate::token::new_session_id().expect("id")
        ));
        let token = ControlToken::generate().expect("token");
        assert_eq!(load_mode(&path, &token), None);
        save_mode(&path, &token, OperatorModeCode::Paused, [true, false]).expect("save");
        assert_eq!(
            load_mode(&path, &token),
            Some((OperatorModeCode::Paused, [true, false]))
        );
        let other = ControlToken::generate().expect("token");
        assert_eq!(load_mode(&path, &other), None);
        let _ = std::fs::remove_file(&path);
    }
}
