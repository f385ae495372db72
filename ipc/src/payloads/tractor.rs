//! Hardware-layer messages of the tractor that pulls the robot's trailer along the row: the tractor
//! halts at a harvest location and advances to the next when the robot is done ([dual-arm
//! sec. 2.2, 4.1]). The driver sends an absolute target along the row; the device
//! answers with the trailer's position at its own steady rate.

use crate::header::Header;
use crate::wire_code::WireCode;
use iceoryx2::prelude::ZeroCopySend;
use serde::{Deserialize, Serialize};

/// What became of the last tractor command (code in [`TractorFeedback::status`]).
#[repr(u8)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, crate::WireEnum)]
pub enum TractorStatus {
    /// Carried out (or being carried out).
    Ok = 0,
    /// Refused (target behind the trailer, past the end of the row, or not finite); the
    /// tractor kept its previous target.
    Refused = 1,
}

/// Driver -> device: drive to a position along the row, or stop.
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
#[type_name("harvest.TractorCommand.v1")]
pub struct TractorCommand {
    /// Sequence number, capture and publish stamps (ns, stack clock); see [`Header`].
    pub header: Header,
    /// Where the trailer should stop, metres along the row (absolute, so a repeated or
    /// replayed command does not advance twice).
    pub target_m: f64,
    /// 1: stop where it is (the target is ignored); 0: drive to the target.
    pub stop: u8,
    /// Zero; keeps the following fields aligned.
    pub _reserved: [u8; 7],
}

/// Device -> driver: the trailer's position along the row.
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
#[type_name("harvest.TractorFeedback.v1")]
pub struct TractorFeedback {
    /// `capture_ns` is when the position was measured; see [`Header`].
    pub header: Header,
    /// Trailer position, metres along the row.
    pub position_m: f64,
    /// Speed along the row, m/s.
    pub velocity_m_per_s: f64,
    /// The target it drives to (its position after a stop).
    pub target_m: f64,
    /// End of the row: targets beyond it are refused, m.
    pub row_end_m: f64,
    /// `header.capture_ns` of the last command the device processed (0: none yet).
    pub last_command_ns: u64,
    /// 1 while the tractor moves toward its target.
    pub in_motion: u8,
    /// What became of the last command.
    pub status: WireCode<TractorStatus>,
    /// Zero; keeps the following fields aligned.
    pub _reserved: [u8; 6],
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::payload::Payload;

    #[test]
    fn feedback_round_trips_through_the_codec() {
        let feedback = TractorFeedback {
            header: Header {
                msg_seq: 1,
                capture_ns: 2,
                publish_ns: 3,
            },
            position_m: 1.25,
            velocity_m_per_s: 0.3,
            target_m: 2.0,
            row_end_m: 9.0,
            last_command_ns: 7,
            in_motion: 1,
            status: TractorStatus::Refused.into(),
            _reserved: [0; 6],
        };
        let mut bytes = Vec::new();
        feedback.encode(&mut bytes).expect("encode");
        let mut decoded = TractorFeedback::default();
        TractorFeedback::decode_into(&bytes, &mut decoded).expect("decode");
        assert_eq!(decoded, feedback);
    }
}
