//! H.264 Annex B byte streams read back: the NAL units between start codes, their types, and
//! the slice type of each coded slice (what tells I, P and B frames apart).
//!
//! The continuous record's video (`camera/video`, `foxglove.CompressedVideo`) must hold one
//! frame per message, SPS and PPS with every IDR and no B slices (Foxglove decodes without
//! look-ahead); [`FrameNals::of`] tells what a message holds so writers and tests can check it.
//! Only the first two fields of a slice header are parsed (ITU-T H.264 7.3.3:
//! `first_mb_in_slice`, `slice_type`, both Exp-Golomb after removing emulation prevention bytes).

/// NAL unit types (ITU-T H.264 Table 7-1) this module names.
pub mod nal_type {
    /// Coded slice of a non-IDR picture.
    pub const SLICE: u8 = 1;
    /// Coded slice of an IDR picture.
    pub const IDR_SLICE: u8 = 5;
    /// Supplemental enhancement information.
    pub const SEI: u8 = 6;
    /// Sequence parameter set.
    pub const SPS: u8 = 7;
    /// Picture parameter set.
    pub const PPS: u8 = 8;
    /// Access unit delimiter.
    pub const AUD: u8 = 9;
}

/// Slice types (`slice_type % 5`, ITU-T H.264 Table 7-6).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SliceType {
    P,
    B,
    I,
    Sp,
    Si,
}

impl SliceType {
    fn from_code(code: u32) -> Self {
        match code % 5 {
            0 => Self::P,
            1 => Self::B,
            2 => Self::I,
            3 => Self::Sp,
            _ => Self::Si,
        }
    }
}

/// A byte stream that is not what the continuous record's video must be.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum AnnexBError {
    /// The data does not start with a start code (`00 00 01` or `00 00 00 01`).
    #[error("no Annex B start code at the beginning")]
    NoStartCode,
    /// A NAL unit is empty or its forbidden bit is set.
    #[error("NAL unit {index} is malformed")]
    BadNalUnit { index: usize },
    /// A slice header ends before its slice type.
    #[error("slice header of NAL unit {index} is truncated")]
    TruncatedSlice { index: usize },
}

/// The NAL units of an Annex B stream, without their start codes (trailing zero bytes of a
/// unit belong to the next start code and are cut).
pub fn nal_units(stream: &[u8]) -> Result<Vec<&[u8]>, AnnexBError> {
    let starts = start_codes(stream);
    match starts.first() {
        Some(&(0, _)) => {}
        _ => return Err(AnnexBError::NoStartCode),
    }
    let mut units = Vec::with_capacity(starts.len());
    for (index, &(position, length)) in starts.iter().enumerate() {
        let begin = position + length;
        let mut end = starts
            .get(index + 1)
            .map_or(stream.len(), |&(next, _)| next);
        while end > begin && stream[end - 1] == 0 {
            end -= 1;
        }
        units.push(&stream[begin..end]);
    }
    Ok(units)
}

/// (offset, length) of each start code: `00 00 01`, or `00 00 00 01` counted as 4 bytes.
fn start_codes(stream: &[u8]) -> Vec<(usize, usize)> {
    let mut starts = Vec::new();
    let mut index = 0;
    while index + 3 <= stream.len() {
        if stream[index] == 0 && stream[index + 1] == 0 && stream[index + 2] == 1 {
            if index > 0 && stream[index - 1] == 0 {
                starts.push((index - 1, 4));
            } else {
                starts.push((index, 3));
            }
            index += 3;
        } else {
            index += 1;
        }
    }
    starts
}

/// The type of a NAL unit (its header's low five bits).
pub fn unit_type(unit: &[u8]) -> Option<u8> {
    unit.first().map(|header| header & 0x1f)
}

/// What one access unit (one `CompressedVideo` message) holds.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct FrameNals {
    /// Type of every NAL unit, in order.
    pub unit_types: Vec<u8>,
    /// Slice type of every coded slice, in order.
    pub slice_types: Vec<SliceType>,
}

impl FrameNals {
    /// Parses one access unit.
    pub fn of(stream: &[u8]) -> Result<Self, AnnexBError> {
        let mut frame = Self::default();
        for (index, unit) in nal_units(stream)?.into_iter().enumerate() {
            let header = *unit.first().ok_or(AnnexBError::BadNalUnit { index })?;
            if header & 0x80 != 0 {
                return Err(AnnexBError::BadNalUnit { index });
            }
            let kind = header & 0x1f;
            frame.unit_types.push(kind);
            if kind == nal_type::SLICE || kind == nal_type::IDR_SLICE {
                frame.slice_types.push(slice_type(&unit[1..], index)?);
            }
        }
        Ok(frame)
    }

    /// True when the access unit is an IDR picture.
    pub fn is_idr(&self) -> bool {
        self.unit_types.contains(&nal_type::IDR_SLICE)
    }

    /// True when an IDR carries its SPS and PPS (what a decoder needs to start there).
    pub fn idr_has_parameter_sets(&self) -> bool {
        self.is_idr()
            && self.unit_types.contains(&nal_type::SPS)
            && self.unit_types.contains(&nal_type::PPS)
    }

    /// True when any slice is a B slice.
    pub fn has_b_slices(&self) -> bool {
        self.slice_types.contains(&SliceType::B)
    }

    /// Coded slices in the access unit.
    pub fn slice_count(&self) -> usize {
        self.slice_types.len()
    }
}

/// `slice_type` of a slice header (`rbsp` follows the NAL header byte).
fn slice_type(escaped: &[u8], index: usize) -> Result<SliceType, AnnexBError> {
    // The first two Exp-Golomb codes fit in a few bytes; unescape just those.
    let head = unescape(&escaped[..escaped.len().min(16)]);
    let mut bits = BitReader {
        bytes: &head,
        position: 0,
    };
    let truncated = AnnexBError::TruncatedSlice { index };
    let _first_mb_in_slice = bits.exp_golomb().ok_or(truncated.clone())?;
    let code = bits.exp_golomb().ok_or(truncated)?;
    Ok(SliceType::from_code(code))
}

/// Removes emulation prevention bytes (`00 00 03` -> `00 00`).
fn unescape(escaped: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(escaped.len());
    let mut zeros = 0;
    for &byte in escaped {
        if zeros >= 2 && byte == 3 {
            zeros = 0;
            continue;
        }
        zeros = if byte == 0 { zeros + 1 } else { 0 };
        out.push(byte);
    }
    out
}

struct BitReader<'a> {
    bytes: &'a [u8],
    position: usize,
}

impl BitReader<'_> {
    fn bit(&mut self) -> Option<u32> {
        let byte = *self.bytes.get(self.position / 8)?;
        let bit = (byte >> (7 - self.position % 8)) & 1;
        self.position += 1;
        Some(u32::from(bit))
    }

    /// An unsigned Exp-Golomb code, `ue(v)`.
    fn exp_golomb(&mut self) -> Option<u32> {
        let mut leading_zeros = 0;
        while self.bit()? == 0 {
            leading_zeros += 1;
            if leading_zeros > 31 {
                return None;
            }
        }
        let mut value: u32 = 0;
        for _ in 0..leading_zeros {
            value = (value << 1) | self.bit()?;
        }
        Some((1u32 << leading_zeros) - 1 + value)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn splits_units_on_both_start_code_lengths() {
        let stream = [
            0, 0, 0, 1, 0x67, 1, 2, 0, 0, 1, 0x68, 3, 0, 0, 0, 1, 0x65, 0x88,
        ];
        let units = nal_units(&stream).expect("units");
        assert_eq!(
            units,
            vec![&[0x67, 1, 2][..], &[0x68, 3][..], &[0x65, 0x88][..]]
        );
        assert_eq!(nal_units(&[1, 2, 3]), Err(AnnexBError::NoStartCode));
    }

    #[test]
    fn reads_slice_types() {
        // first_mb_in_slice = 0 ("1"), slice_type = 7 (I, "0001000") -> 1000 1000 = 0x88.
        let idr = [
            0, 0, 0, 1, 0x67, 0x42, 0, 0, 1, 0x68, 0xce, 0, 0, 1, 0x65, 0x88, 0x80,
        ];
        let frame = FrameNals::of(&idr).expect("frame");
        assert!(frame.is_idr() && frame.idr_has_parameter_sets());
        assert_eq!(frame.slice_types, vec![SliceType::I]);
        // slice_type = 5 (P, "00110"): 1 00110 00 = 0x98.
        let p = [0, 0, 1, 0x41, 0x98];
        assert_eq!(
            FrameNals::of(&p).expect("p").slice_types,
            vec![SliceType::P]
        );
        // slice_type = 6 (B, "00111"): 1 00111 00 = 0x9c.
        let b = [0, 0, 1, 0x01, 0x9c];
        assert!(FrameNals::of(&b).expect("b").has_b_slices());
        // Emulation prevention inside the header is removed before reading.
        assert_eq!(unescape(&[0, 0, 3, 1]), vec![0, 0, 1]);
    }
}
