//! Standard base64 (RFC 4648, with padding), for binary fields in JSON exports (Foxglove's
//! `contentEncoding: base64`).

const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";

/// Appends the base64 encoding of `bytes` to `out`.
pub fn encode_into(bytes: &[u8], out: &mut String) {
    out.reserve(bytes.len().div_ceil(3) * 4);
    let mut chunks = bytes.chunks_exact(3);
    for chunk in &mut chunks {
        let group = (u32::from(chunk[0]) << 16) | (u32::from(chunk[1]) << 8) | u32::from(chunk[2]);
        for shift in [18, 12, 6, 0] {
            out.push(ALPHABET[(group >> shift & 0x3f) as usize] as char);
        }
    }
    match *chunks.remainder() {
        [a] => {
            let group = u32::from(a) << 16;
            out.push(ALPHABET[(group >> 18 & 0x3f) as usize] as char);
            out.push(ALPHABET[(group >> 12 & 0x3f) as usize] as char);
            out.push_str("==");
        }
        [a, b] => {
            let group = (u32::from(a) << 16) | (u32::from(b) << 8);
            out.push(ALPHABET[(group >> 18 & 0x3f) as usize] as char);
            out.push(ALPHABET[(group >> 12 & 0x3f) as usize] as char);
            out.push(ALPHABET[(group >> 6 & 0x3f) as usize] as char);
            out.push('=');
        }
        _ => {}
    }
}

/// The base64 encoding of `bytes`.
pub fn encode(bytes: &[u8]) -> String {
    let mut out = String::new();
    encode_into(bytes, &mut out);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rfc4648_test_vectors() {
        assert_eq!(encode(b""), "");
        assert_eq!(encode(b"f"), "Zg==");
        assert_eq!(encode(b"fo"), "Zm8=");
        assert_eq!(encode(b"foo"), "Zm9v");
        assert_eq!(encode(b"foob"), "Zm9vYg==");
        assert_eq!(encode(b"fooba"), "Zm9vYmE=");
        assert_eq!(encode(b"foobar"), "Zm9vYmFy");
        assert_eq!(encode(&[0xff, 0xfe, 0x00]), "//4A");
    }
}
