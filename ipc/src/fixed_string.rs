//! A fixed-capacity UTF-8 string for payloads (process names, reasons).

use iceoryx2::prelude::ZeroCopySend;
use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// Up to `N` bytes of UTF-8, zero padded. Longer input is truncated at a character boundary.
#[repr(C)]
#[derive(Clone, Copy, PartialEq, Eq, ZeroCopySend, crate::AnyBitPattern)]
pub struct FixedString<const N: usize> {
    bytes: [u8; N],
}

impl<const N: usize> FixedString<N> {
    /// `text`, truncated to `N` bytes at a character boundary.
    pub fn new(text: &str) -> Self {
        let mut bytes = [0u8; N];
        let mut end = text.len().min(N);
        while !text.is_char_boundary(end) {
            end -= 1;
        }
        bytes[..end].copy_from_slice(&text.as_bytes()[..end]);
        Self { bytes }
    }

    /// A string of what `args` formats to, truncated like [`Self::new`]; no allocation
    /// (`FixedString::format(format_args!("{a} -> {b}"))`).
    pub fn format(args: std::fmt::Arguments<'_>) -> Self {
        let mut out = Self::default();
        // Writing to a FixedString never fails (it truncates).
        let _ = std::fmt::Write::write_fmt(&mut out, args);
        out
    }

    /// The text up to the first zero byte (`<invalid utf-8>` for bytes that are not UTF-8).
    pub fn as_str(&self) -> &str {
        let end = self.bytes.iter().position(|&b| b == 0).unwrap_or(N);
        std::str::from_utf8(&self.bytes[..end]).unwrap_or("<invalid utf-8>")
    }
}

/// Appends, truncating at a character boundary once full (never an error: payload text is
/// best-effort).
impl<const N: usize> std::fmt::Write for FixedString<N> {
    fn write_str(&mut self, text: &str) -> std::fmt::Result {
        let start = self.bytes.iter().position(|&b| b == 0).unwrap_or(N);
        let room = N - start;
        let mut end = text.len().min(room);
        while !text.is_char_boundary(end) {
            end -= 1;
        }
        self.bytes[start..start + end].copy_from_slice(&text.as_bytes()[..end]);
        Ok(())
    }
}

impl<const N: usize> Default for FixedString<N> {
    fn default() -> Self {
        Self { bytes: [0u8; N] }
    }
}

impl<const N: usize> std::fmt::Debug for FixedString<N> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{:?}", self.as_str())
    }
}

impl<const N: usize> std::fmt::Display for FixedString<N> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

impl<const N: usize> Serialize for FixedString<N> {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.serialize_str(self.as_str())
    }
}

/// Written as a string: a u64 byte count, then the UTF-8 bytes (at most `N`).
impl<const N: usize> crate::schema::Describe for FixedString<N> {
    fn shape() -> crate::schema::Shape {
        crate::schema::Shape::Text { max_bytes: N }
    }
}

impl<'de, const N: usize> Deserialize<'de> for FixedString<N> {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        let text = String::deserialize(deserializer)?;
        Ok(Self::new(&text))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn truncates_at_char_boundary() {
        let name = FixedString::<4>::new("aéé");
        assert_eq!(name.as_str(), "aé");
        assert_eq!(FixedString::<8>::new("camera").as_str(), "camera");
    }

    #[test]
    fn formats_in_place_and_truncates_at_char_boundary() {
        let text = FixedString::<12>::format(format_args!("{} -> {:?}", 7, "x"));
        assert_eq!(text.as_str(), "7 -> \"x\"");
        let cut = FixedString::<5>::format(format_args!("ab{}", "cdé"));
        assert_eq!(cut.as_str(), "abcd");
        let full = FixedString::<4>::format(format_args!("{}{}", "abcd", "ef"));
        assert_eq!(full.as_str(), "abcd");
    }
}
