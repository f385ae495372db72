//! What the benchmark writes into every message and how the receiver checks it.
//!
//! Fairness rule: the sender writes a value that changes with `msg_seq` into **every 64-byte
//! line** of the payload body on every send (so no transport can profit from data that did not
//! change, and the receiver's caches never hold the new lines), and the receiver reads back a
//! spread sample of [`CHECKED_LINES`] lines (first and last included) and compares them with
//! the expected values. A stale slot or torn copy fails the run with [`BenchError::Corrupt`].

use crate::bench_payload::BenchPayload;
use crate::error::BenchError;
use harvest_ipc::catalogue::{self, Channel, Qos};
use harvest_ipc::payloads::apple_detections::MAX_APPLES_PER_FRAME;
use harvest_ipc::payloads::{
    AppleDetection, AppleDetections, LaserScanRequest, LocalizationMethod, RgbdFrame,
};
use harvest_ipc::{MonotonicClock, Payload};

/// Bytes per written line (the cache-line size of x86-64 and most ARM cores).
pub const LINE_BYTES: usize = 64;
/// Lines the receiver reads back per message.
pub const CHECKED_LINES: usize = 64;
/// Payloads up to this size use the small-message QoS in the raw iceoryx2 baseline.
const SMALL_QOS_MAX_BYTES: usize = 64 * 1024;

/// Which phase of a case a message belongs to; travels in the payload as an integer code.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Phase {
    /// Stop-and-wait, not recorded.
    Warmup = 1,
    /// Stop-and-wait, latency recorded.
    Measure = 2,
    /// The last recorded stop-and-wait message.
    MeasureLast = 3,
    /// Windowed stream for throughput.
    Stream = 4,
    /// The last message of the stream.
    StreamLast = 5,
}

impl Phase {
    pub fn code(self) -> u64 {
        self as u64
    }

    pub fn from_code(code: u64) -> Option<Self> {
        match code {
            1 => Some(Self::Warmup),
            2 => Some(Self::Measure),
            3 => Some(Self::MeasureLast),
            4 => Some(Self::Stream),
            5 => Some(Self::StreamLast),
            _ => None,
        }
    }
}

/// A payload type the benchmark can send: how to fill and check it, and where it lives.
pub trait BenchMessage: Payload {
    /// The catalogue channel carrying this type, if it is a catalogue type.
    fn catalogue_channel() -> Option<Channel<Self>>;
    /// The channel our layer uses: the catalogue channel, else an ad-hoc channel on `topic`
    /// with [`Self::qos`] (`harvest_ipc::Channel::ad_hoc`, not part of the stack catalogue).
    fn channel(topic: &'static str) -> Channel<Self> {
        Self::catalogue_channel().unwrap_or_else(|| Channel::ad_hoc(topic, Self::qos()))
    }
    /// QoS of our layer's channel and of the raw iceoryx2 baseline (the catalogue channel's,
    /// if there is one).
    fn qos() -> Qos {
        match Self::catalogue_channel() {
            Some(channel) => channel.spec.qos,
            None if std::mem::size_of::<Self>() <= SMALL_QOS_MAX_BYTES => Qos::SMALL,
            None => Qos::FRAMES,
        }
    }
    /// Writes the phase code and a `msg_seq`-dependent value into every line of the body.
    /// Does not touch the header.
    fn fill(&mut self, msg_seq: u64, phase: Phase);
    /// Writes only the phase code (the diagnostic `--sender-write none|elsewhere` variants).
    fn set_phase(&mut self, phase: Phase);
    /// The phase code written by [`Self::fill`] or [`Self::set_phase`].
    fn phase_code(&self) -> u64;
    /// Reads back a sample of lines against `header().msg_seq` and returns the phase.
    fn check(&self, payload: &'static str) -> Result<Phase, BenchError>;
}

/// The value written into line `line` of message `msg_seq` (a cheap integer hash).
pub fn line_value(msg_seq: u64, line: usize) -> u64 {
    msg_seq.wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ (line as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
        ^ 0x5851_F42D_4C95_7F2D
}

/// Writes `line_value(msg_seq, first_line + i)` into the first 8 bytes of each 64-byte line.
pub fn fill_byte_lines(bytes: &mut [u8], msg_seq: u64, first_line: usize) {
    for (index, line) in bytes.chunks_mut(LINE_BYTES).enumerate() {
        let value = line_value(msg_seq, first_line + index).to_le_bytes();
        let len = line.len().min(8);
        line[..len].copy_from_slice(&value[..len]);
    }
}

/// Checks a spread sample of the lines written by [`fill_byte_lines`].
pub fn check_byte_lines(bytes: &[u8], msg_seq: u64, first_line: usize) -> Result<(), LineMismatch> {
    let lines = bytes.len().div_ceil(LINE_BYTES);
    for index in sampled_lines(lines) {
        let start = index * LINE_BYTES;
        let len = (bytes.len() - start).min(8);
        let expected = line_value(msg_seq, first_line + index).to_le_bytes();
        let mut found = [0u8; 8];
        found[..len].copy_from_slice(&bytes[start..start + len]);
        let mut wanted = [0u8; 8];
        wanted[..len].copy_from_slice(&expected[..len]);
        if found != wanted {
            return Err(LineMismatch {
                line: first_line + index,
                expected: u64::from_le_bytes(wanted),
                found: u64::from_le_bytes(found),
            });
        }
    }
    Ok(())
}

/// `u16` words per 64-byte line.
const WORDS_PER_LINE: usize = LINE_BYTES / 2;

/// [`fill_byte_lines`] for a `u16` buffer: the value goes into the first 4 words of each line.
pub fn fill_word_lines(words: &mut [u16], msg_seq: u64, first_line: usize) {
    for (index, line) in words.chunks_mut(WORDS_PER_LINE).enumerate() {
        let value = line_value(msg_seq, first_line + index);
        for (slot, word) in line.iter_mut().take(4).enumerate() {
            *word = (value >> (16 * slot)) as u16;
        }
    }
}

/// [`check_byte_lines`] for a `u16` buffer.
pub fn check_word_lines(
    words: &[u16],
    msg_seq: u64,
    first_line: usize,
) -> Result<(), LineMismatch> {
    let lines = words.len().div_ceil(WORDS_PER_LINE);
    for index in sampled_lines(lines) {
        let line = &words[index * WORDS_PER_LINE..];
        let used = line.len().min(4);
        let mask = if used == 4 {
            u64::MAX
        } else {
            (1u64 << (16 * used)) - 1
        };
        let found = line
            .iter()
            .take(used)
            .enumerate()
            .fold(0u64, |acc, (slot, &word)| {
                acc | (u64::from(word) << (16 * slot))
            });
        let expected = line_value(msg_seq, first_line + index) & mask;
        if found != expected {
            return Err(LineMismatch {
                line: first_line + index,
                expected,
                found,
            });
        }
    }
    Ok(())
}

/// A checked line that does not hold its expected value.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LineMismatch {
    pub line: usize,
    pub expected: u64,
    pub found: u64,
}

impl LineMismatch {
    fn into_error(self, payload: &'static str, msg_seq: u64) -> BenchError {
        BenchError::Corrupt {
            payload,
            msg_seq,
            line: self.line,
            expected: self.expected,
            found: self.found,
        }
    }
}

/// Indices of the lines checked out of `lines`: evenly spread, first and last included.
fn sampled_lines(lines: usize) -> impl Iterator<Item = usize> {
    let samples = lines.min(CHECKED_LINES);
    (0..samples).map(move |k| {
        if samples <= 1 {
            0
        } else {
            k * (lines - 1) / (samples - 1)
        }
    })
}

/// The phase of a received code, or [`BenchError::UnknownPhase`].
pub fn phase_of(code: u64, payload: &'static str, msg_seq: u64) -> Result<Phase, BenchError> {
    Phase::from_code(code).ok_or(BenchError::UnknownPhase {
        payload,
        msg_seq,
        code,
    })
}

impl<const N: usize> BenchMessage for BenchPayload<N> {
    fn catalogue_channel() -> Option<Channel<Self>> {
        None
    }

    fn fill(&mut self, msg_seq: u64, phase: Phase) {
        self.phase = phase.code();
        fill_byte_lines(&mut self.bytes, msg_seq, 0);
    }

    fn set_phase(&mut self, phase: Phase) {
        self.phase = phase.code();
    }

    fn phase_code(&self) -> u64 {
        self.phase
    }

    fn check(&self, payload: &'static str) -> Result<Phase, BenchError> {
        let msg_seq = self.header.msg_seq;
        check_byte_lines(&self.bytes, msg_seq, 0).map_err(|m| m.into_error(payload, msg_seq))?;
        phase_of(self.phase, payload, msg_seq)
    }
}

/// 64 bytes: the smallest message of the catalogue. Every field after the header is written.
impl BenchMessage for LaserScanRequest {
    fn catalogue_channel() -> Option<Channel<Self>> {
        Some(catalogue::LASER_SCAN_REQUEST)
    }

    fn set_phase(&mut self, phase: Phase) {
        self.request_seq = phase.code() as u32;
    }

    fn phase_code(&self) -> u64 {
        u64::from(self.request_seq)
    }

    fn fill(&mut self, msg_seq: u64, phase: Phase) {
        self.request_seq = phase.code() as u32;
        self.apple_id = line_value(msg_seq, 0) as u32;
        for (axis, value) in self.rough_position_in_camera_m.iter_mut().enumerate() {
            *value = f64::from_bits(line_value(msg_seq, 1 + axis));
        }
        self.rough_radius_m = f64::from_bits(line_value(msg_seq, 4));
    }

    fn check(&self, payload: &'static str) -> Result<Phase, BenchError> {
        let msg_seq = self.header.msg_seq;
        let mut found = [
            u64::from(self.apple_id),
            0,
            0,
            0,
            self.rough_radius_m.to_bits(),
        ];
        for (axis, value) in self.rough_position_in_camera_m.iter().enumerate() {
            found[1 + axis] = value.to_bits();
        }
        for (line, &value) in found.iter().enumerate() {
            let mut expected = line_value(msg_seq, line);
            if line == 0 {
                expected &= u64::from(u32::MAX);
            }
            if value != expected {
                return Err(LineMismatch {
                    line,
                    expected,
                    found: value,
                }
                .into_error(payload, msg_seq));
            }
        }
        phase_of(u64::from(self.request_seq), payload, msg_seq)
    }
}

/// About 5.7 kB: a full list of detections, every detection rewritten.
impl BenchMessage for AppleDetections {
    fn catalogue_channel() -> Option<Channel<Self>> {
        Some(catalogue::PERCEPTION_APPLES)
    }

    fn set_phase(&mut self, phase: Phase) {
        self.processing_ns = phase.code();
    }

    fn phase_code(&self) -> u64 {
        self.processing_ns
    }

    fn fill(&mut self, msg_seq: u64, phase: Phase) {
        self.processing_ns = phase.code();
        self.source_frame_seq = msg_seq;
        self.source_capture_ns = MonotonicClock::read_ns();
        self.apples.clear();
        for index in 0..MAX_APPLES_PER_FRAME {
            let value = line_value(msg_seq, index);
            let detection = AppleDetection {
                apple_id: value as u32,
                method: LocalizationMethod::ClusterCentroid.into(),
                position_in_camera_m: [f64::from_bits(value), 0.0, 0.0],
                confidence: 1.0,
                ..AppleDetection::default()
            };
            // Cannot fail: the list was cleared and holds MAX_APPLES_PER_FRAME items.
            let _ = self.apples.push(detection);
        }
    }

    fn check(&self, payload: &'static str) -> Result<Phase, BenchError> {
        let msg_seq = self.header.msg_seq;
        if self.apples.len() != MAX_APPLES_PER_FRAME {
            return Err(LineMismatch {
                line: 0,
                expected: MAX_APPLES_PER_FRAME as u64,
                found: self.apples.len() as u64,
            }
            .into_error(payload, msg_seq));
        }
        for (index, detection) in self.apples.iter().enumerate() {
            let expected = line_value(msg_seq, index);
            let found = detection.position_in_camera_m[0].to_bits();
            if found != expected || detection.apple_id != expected as u32 {
                return Err(LineMismatch {
                    line: index,
                    expected,
                    found,
                }
                .into_error(payload, msg_seq));
            }
        }
        phase_of(self.processing_ns, payload, msg_seq)
    }
}

/// About 6.8 MB: every line of the colour and depth images is rewritten; the phase travels in
/// `meta.exposure_us` (the frame's metadata is otherwise left as it was).
impl BenchMessage for RgbdFrame {
    fn catalogue_channel() -> Option<Channel<Self>> {
        Some(catalogue::CAMERA_RGBD)
    }

    fn set_phase(&mut self, phase: Phase) {
        self.meta.exposure_us = phase.code() as u32;
    }

    fn phase_code(&self) -> u64 {
        u64::from(self.meta.exposure_us)
    }

    fn fill(&mut self, msg_seq: u64, phase: Phase) {
        self.meta.exposure_us = phase.code() as u32;
        fill_byte_lines(&mut self.rgb, msg_seq, 0);
        fill_word_lines(&mut self.depth_mm, msg_seq, rgb_lines());
    }

    fn check(&self, payload: &'static str) -> Result<Phase, BenchError> {
        let msg_seq = self.header.msg_seq;
        check_byte_lines(&self.rgb, msg_seq, 0).map_err(|m| m.into_error(payload, msg_seq))?;
        check_word_lines(&self.depth_mm, msg_seq, rgb_lines())
            .map_err(|m| m.into_error(payload, msg_seq))?;
        phase_of(u64::from(self.meta.exposure_us), payload, msg_seq)
    }
}

fn rgb_lines() -> usize {
    harvest_ipc::payloads::rgbd_frame::RGB_BYTES.div_ceil(LINE_BYTES)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bench_payload::zeroed_box;

    #[test]
    fn every_line_changes_with_the_sequence_number() {
        let mut bytes = vec![0u8; 1000];
        fill_byte_lines(&mut bytes, 1, 0);
        let first = bytes.clone();
        fill_byte_lines(&mut bytes, 2, 0);
        for (line, (a, b)) in first
            .chunks(LINE_BYTES)
            .zip(bytes.chunks(LINE_BYTES))
            .enumerate()
        {
            assert_ne!(a, b, "line {line} did not change");
        }
        assert!(check_byte_lines(&bytes, 2, 0).is_ok());
        let mismatch = check_byte_lines(&bytes, 1, 0).expect_err("stale data must be caught");
        assert_eq!(mismatch.line, 0);
    }

    #[test]
    fn a_torn_last_line_is_caught() {
        let mut words = vec![0u16; 1000];
        fill_word_lines(&mut words, 5, 3);
        assert!(check_word_lines(&words, 5, 3).is_ok());
        let last_line_start = (words.len() - 1) / WORDS_PER_LINE * WORDS_PER_LINE;
        words[last_line_start] ^= 1;
        let mismatch = check_word_lines(&words, 5, 3).expect_err("torn line must be caught");
        assert_eq!(mismatch.line, 3 + last_line_start / WORDS_PER_LINE);
    }

    #[test]
    fn sampled_lines_cover_first_and_last() {
        let lines: Vec<_> = sampled_lines(1000).collect();
        assert_eq!(lines.len(), CHECKED_LINES);
        assert_eq!(lines[0], 0);
        assert_eq!(*lines.last().expect("non-empty"), 999);
        assert_eq!(sampled_lines(1).collect::<Vec<_>>(), vec![0]);
        assert_eq!(sampled_lines(3).collect::<Vec<_>>(), vec![0, 1, 2]);
    }

    fn round_trip<T: BenchMessage>(name: &'static str) {
        let mut message = zeroed_box::<T>();
        message.header_mut().msg_seq = 41;
        message.fill(41, Phase::MeasureLast);
        assert_eq!(
            message.check(name).expect("fresh message"),
            Phase::MeasureLast
        );
        let mut encoded = Vec::new();
        message.encode(&mut encoded).expect("encode");
        let mut copy = zeroed_box::<T>();
        T::decode_into(&encoded, &mut copy).expect("decode");
        assert_eq!(copy.check(name).expect("decoded copy"), Phase::MeasureLast);
        copy.header_mut().msg_seq = 42;
        assert!(matches!(
            copy.check(name),
            Err(BenchError::Corrupt { msg_seq: 42, .. })
        ));
    }

    #[test]
    fn every_payload_type_fills_checks_and_survives_the_codec() {
        round_trip::<LaserScanRequest>("scan-request");
        round_trip::<AppleDetections>("detections");
        round_trip::<RgbdFrame>("rgbd");
        round_trip::<BenchPayload<32>>("64B");
        round_trip::<BenchPayload<4064>>("4KiB");
    }

    #[test]
    fn catalogue_types_use_their_channel_qos() {
        assert_eq!(<RgbdFrame as BenchMessage>::qos(), Qos::FRAMES);
        assert_eq!(<BenchPayload<32> as BenchMessage>::qos(), Qos::SMALL);
        assert_eq!(
            <BenchPayload<{ 1 << 20 }> as BenchMessage>::qos(),
            Qos::FRAMES
        );
    }
}
