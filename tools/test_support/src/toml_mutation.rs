//! Mutations of TOML text for the property tests of every
//! reader of outside files (launch files, scenarios, settings, calibrations): values replaced
//! by anything (NaN, infinities, signs, extremes, wrong types), lines dropped or doubled, bytes
//! changed. One generator, so every reader is explored the same way.

use proptest::prelude::*;
use std::path::PathBuf;

/// Values that break settings: NaN, infinities, signs, zeros, extremes, wrong types.
pub const WILD_VALUES: &[&str] = &[
    "nan",
    "inf",
    "-inf",
    "-1",
    "0",
    "-0.0",
    "1e308",
    "5e-324",
    "18446744073709551615",
    "9223372036854775807",
    "-9223372036854775808",
    "\"\"",
    "\"x\"",
    "true",
    "[]",
    "[nan, inf, -1]",
    "{}",
    "0.000001",
    "100000",
];

/// One edit of a TOML text.
#[derive(Debug, Clone)]
pub enum TomlEdit {
    /// The value of the n-th `key = value` line replaced.
    Value(prop::sample::Index, &'static str),
    /// The n-th line removed.
    DropLine(prop::sample::Index),
    /// The n-th line written twice.
    DuplicateLine(prop::sample::Index),
    /// One byte replaced (syntax errors, cut strings, control characters).
    Byte(prop::sample::Index, u8),
}

pub fn toml_edit() -> impl Strategy<Value = TomlEdit> {
    prop_oneof![
        6 => (any::<prop::sample::Index>(), prop::sample::select(WILD_VALUES))
            .prop_map(|(i, v)| TomlEdit::Value(i, v)),
        1 => any::<prop::sample::Index>().prop_map(TomlEdit::DropLine),
        1 => any::<prop::sample::Index>().prop_map(TomlEdit::DuplicateLine),
        1 => (any::<prop::sample::Index>(), any::<u8>()).prop_map(|(i, b)| TomlEdit::Byte(i, b)),
    ]
}

/// `text` with `edits` applied in order.
pub fn mutate_toml(text: &str, edits: &[TomlEdit]) -> String {
    let mut lines: Vec<String> = text.lines().map(str::to_owned).collect();
    for edit in edits {
        if lines.is_empty() {
            break;
        }
        match edit {
            TomlEdit::Value(index, value) => {
                let assignments: Vec<usize> = (0..lines.len())
                    .filter(|&i| !lines[i].trim_start().starts_with('#') && lines[i].contains('='))
                    .collect();
                if assignments.is_empty() {
                    continue;
                }
                let line = &mut lines[assignments[index.index(assignments.len())]];
                if let Some(at) = line.find('=') {
                    line.truncate(at + 1);
                    line.push(' ');
                    line.push_str(value);
                }
            }
            TomlEdit::DropLine(index) => {
                let at = index.index(lines.len());
                lines.remove(at);
            }
            TomlEdit::DuplicateLine(index) => {
                let at = index.index(lines.len());
                let line = lines[at].clone();
                lines.insert(at, line);
            }
            TomlEdit::Byte(index, byte) => {
                let mut bytes = lines.join("\n").into_bytes();
                if bytes.is_empty() {
                    continue;
                }
                let at = index.index(bytes.len());
                bytes[at] = *byte;
                lines = String::from_utf8_lossy(&bytes)
                    .lines()
                    .map(str::to_owned)
                    .collect();
            }
        }
    }
    lines.join("\n")
}

/// Writes `text` to a fresh file in the temporary directory, named after `prefix`, and returns
/// its path (the caller removes it).
pub fn scratch_file(prefix: &str, text: &str) -> PathBuf {
    use std::sync::atomic::{AtomicU64, Ordering};
    static NEXT: AtomicU64 = AtomicU64::new(0);
    let path = std::env::temp_dir().join(format!(
        "{prefix}-{}-{}.toml",
        std::process::id(),
        NEXT.fetch_add(1, Ordering::Relaxed)
    ));
    std::fs::write(&path, text).expect("write the scratch file");
    path
}
