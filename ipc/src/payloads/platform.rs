//! Hardware-layer messages of the platform movement module ([dual-arm sec. 2]): two stepper
//! stages, in-out (toward the canopy) and up-down, behind an Arduino that reports their
//! positions. The driver sends targets; the device answers with position feedback at its own
//! steady rate.

use crate::header::Header;
use crate::wire_code::WireCode;
use iceoryx2::prelude::ZeroCopySend;
use serde::{Deserialize, Serialize};

/// What became of the last platform command (code in [`PlatformFeedback::status`]).
#[repr(u8)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, crate::WireEnum)]
pub enum PlatformStatus {
    /// Carried out (or being carried out).
    Ok = 0,
    /// Refused (target outside the travel or not finite); the stages kept their previous target.
    Refused = 1,
    /// The stages report a fault (stall, limit switch hit).
    Fault = 2,
}

/// Driver -> device: where both stages should go, or stop.
#[repr(C)]
#[derive(
    Debug,
    Clone,
    Copy,
    Default,
    PartialEq,
    ZeroCopySend,
    Serialize,
    Deserialize,
    crate::AnyBitPattern,
    crate::Payload,
)]
#[type_name("harvest.PlatformCommand.v1")]
pub struct PlatformCommand {
    /// Sequence number, capture and publish stamps (ns, stack clock); see [`Header`].
    pub header: Header,
    /// Target of the in-out stage, metres from its home stop, positive toward the canopy.
    pub target_in_out_m: f64,
    /// Target of the up-down stage, metres above its lowest stop.
    pub target_up_down_m: f64,
    /// 1: stop both stages where they are (the targets are ignored); 0: move to the targets.
    pub stop: u8,
    /// Zero; keeps the following fields aligned.
    pub _reserved: [u8; 7],
}

/// Device -> driver: the stages' encoder positions, sampled at the device's feedback rate.
/// `header.capture_ns` is when the encoders were read.
#[repr(C)]
#[derive(
    Debug,
    Clone,
    Copy,
    Default,
    PartialEq,
    ZeroCopySend,
    Serialize,
    Deserialize,
    crate::AnyBitPattern,
    crate::Payload,
)]
#[type_name("harvest.PlatformFeedback.v1")]
pub struct PlatformFeedback {
    /// `capture_ns` is when the encoders were read; see [`Header`].
    pub header: Header,
    /// In-out stage position, metres from its home stop.
    pub in_out_m: f64,
    /// Up-down stage position, metres above its lowest stop.
    pub up_down_m: f64,
    /// In-out stage velocity, m/s.
    pub in_out_velocity_m_per_s: f64,
    /// Up-down stage velocity, m/s.
    pub up_down_velocity_m_per_s: f64,
    /// The targets the device is moving to (its current position after a stop).
    pub target_in_out_m: f64,
    /// The up-down target the device is moving to, metres.
    pub target_up_down_m: f64,
    /// `header.capture_ns` of the last command the device processed (0: none yet), so the
    /// driver knows whether its latest command has been acted on (stamps of the stack clock
    /// increase across driver restarts, unlike a publisher's `msg_seq`).
    pub last_command_ns: u64,
    /// 1 while either stage is still moving toward its target.
    pub in_motion: u8,
    /// What became of the last command.
    pub status: WireCode<PlatformStatus>,
    /// Zero; keeps the following fields aligned.
    pub _reserved: [u8; 6],
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::payload::Payload;

    #[test]
    fn feedback_round_trips_through_the_codec() {
        let feedback = PlatformFeedback {
            header: Header {
                msg_seq: 3,
                capture_ns: 11,
                publish_ns: 12,
            },
            in_out_m: 0.25,
            up_down_m: 0.5,
            in_out_velocity_m_per_s: -0.01,
            up_down_velocity_m_per_s: 0.02,
            target_in_out_m: 0.3,
            target_up_down_m: 0.6,
            last_command_ns: 9,
            in_motion: 1,
            status: PlatformStatus::Refused.into(),
            _reserved: [0; 6],
        };
        let mut bytes = Vec::new();
        feedback.encode(&mut bytes).expect("encode");
        let mut decoded = PlatformFeedback::default();
        PlatformFeedback::decode_into(&bytes, &mut decoded).expect("decode");
        assert_eq!(decoded, feedback);
    }
}
