//! What the sending peer writes before each send: the fair test (every line of the payload),
//! or one of two diagnostic variants that explain where large-payload latency comes from.
//!
//! - `full` (default, the fair test): every 64-byte line of the message body, in place.
//! - `none`: only the phase code; the body keeps whatever the slot held. The transport's own
//!   cost with the sender's caches warm.
//! - `elsewhere`: the same number of lines written into a private buffer of the message's
//!   size (not shared memory), then only the phase code into the message. If latency then
//!   matches `full`, the extra cost is the sender having touched that many bytes (caches and
//!   TLB evicted), not anything about the loaned shared memory.
//!
//! One-way latency never includes the write: `publish_ns` is stamped after it in every variant.

use crate::error::BenchError;
use crate::message::{BenchMessage, Phase, fill_byte_lines, phase_of};
use harvest_ipc::MonotonicClock;
use serde::Serialize;

/// The sender's write before each send (see the module docs).
#[derive(
    Debug, Clone, Copy, Default, PartialEq, Eq, Hash, PartialOrd, Ord, clap::ValueEnum, Serialize,
)]
#[serde(rename_all = "kebab-case")]
pub enum SenderWrite {
    /// Every line of the body, in place (the fair test).
    #[default]
    #[value(name = "full")]
    Full,
    /// Only the phase code.
    #[value(name = "none")]
    None,
    /// Every line of a private buffer of the message's size, then only the phase code.
    #[value(name = "elsewhere")]
    Elsewhere,
}

impl SenderWrite {
    pub fn name(self) -> &'static str {
        match self {
            Self::Full => "full",
            Self::None => "none",
            Self::Elsewhere => "elsewhere",
        }
    }

    /// Checks a received message as this variant wrote it: every sampled line for `full`,
    /// only the phase otherwise (the body was not written).
    pub fn check<T: BenchMessage>(
        self,
        message: &T,
        payload: &'static str,
    ) -> Result<Phase, BenchError> {
        match self {
            Self::Full => message.check(payload),
            Self::None | Self::Elsewhere => {
                phase_of(message.phase_code(), payload, message.header().msg_seq)
            }
        }
    }
}

/// Performs the sender's write; owns the private buffer of the `elsewhere` variant.
#[derive(Debug)]
pub struct PayloadWriter {
    mode: SenderWrite,
    scratch: Vec<u8>,
}

impl PayloadWriter {
    /// For messages of `message_bytes`. The private buffer is allocated and touched once here,
    /// so the variant measures cache and TLB effects, not first-touch page faults.
    pub fn new(mode: SenderWrite, message_bytes: usize) -> Self {
        let scratch = match mode {
            SenderWrite::Elsewhere => vec![1u8; message_bytes],
            SenderWrite::Full | SenderWrite::None => Vec::new(),
        };
        Self { mode, scratch }
    }

    /// Writes message `msg_seq` of `phase` as the variant says (never the header).
    pub fn write<T: BenchMessage>(&mut self, message: &mut T, msg_seq: u64, phase: Phase) {
        match self.mode {
            SenderWrite::Full => message.fill(msg_seq, phase),
            SenderWrite::None => message.set_phase(phase),
            SenderWrite::Elsewhere => {
                fill_byte_lines(&mut self.scratch, msg_seq, 0);
                std::hint::black_box(&mut self.scratch);
                message.set_phase(phase);
            }
        }
    }

    /// [`write`](Self::write), then the header of a transport that does not stamp it itself:
    /// `msg_seq`, `capture_ns` read before writing and `publish_ns` read after, which it
    /// returns (the start of the measured latency).
    pub fn write_stamped<T: BenchMessage>(
        &mut self,
        message: &mut T,
        msg_seq: u64,
        phase: Phase,
    ) -> u64 {
        let capture_ns = MonotonicClock::read_ns();
        self.write(message, msg_seq, phase);
        let header = message.header_mut();
        header.msg_seq = msg_seq;
        header.capture_ns = capture_ns;
        let publish_ns = MonotonicClock::read_ns();
        header.publish_ns = publish_ns;
        publish_ns
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bench_payload::{BenchPayload, zeroed_box};
    use harvest_ipc::payloads::RgbdFrame;

    fn variants_round_trip<T: BenchMessage>(name: &'static str) {
        for mode in [SenderWrite::Full, SenderWrite::None, SenderWrite::Elsewhere] {
            let mut writer = PayloadWriter::new(mode, std::mem::size_of::<T>());
            let mut message = zeroed_box::<T>();
            message.header_mut().msg_seq = 5;
            writer.write(&mut *message, 5, Phase::Measure);
            assert_eq!(mode.check(&*message, name).expect("checks"), Phase::Measure);
            // Only the full write puts the sequence-dependent lines in the message.
            message.header_mut().msg_seq = 6;
            assert_eq!(
                mode.check(&*message, name).is_err(),
                mode == SenderWrite::Full
            );
        }
    }

    #[test]
    fn every_variant_carries_the_phase_and_only_full_writes_the_body() {
        variants_round_trip::<BenchPayload<4064>>("4KiB");
        variants_round_trip::<RgbdFrame>("rgbd");
    }

    #[test]
    fn elsewhere_writes_a_private_buffer_of_the_message_size() {
        let mut writer = PayloadWriter::new(SenderWrite::Elsewhere, 4096);
        let mut message = zeroed_box::<BenchPayload<4064>>();
        writer.write(&mut *message, 3, Phase::Warmup);
        assert_eq!(writer.scratch.len(), 4096);
        assert!(crate::message::check_byte_lines(&writer.scratch, 3, 0).is_ok());
        assert!(message.bytes.iter().all(|&b| b == 0));
    }
}
