//! ALACS laser scans: perception asks for a scan of one apple, the laser process answers.

use crate::header::Header;
use crate::wire_code::WireCode;
use iceoryx2::prelude::ZeroCopySend;
use serde::{Deserialize, Serialize};

/// Images per interval scan (5 images at 1 cm steps, [alacs sec. 3]).
pub const MAX_SCAN_CANDIDATES: usize = 5;

/// Asks the laser process to scan one apple (`laser/scan_request`, from perception).
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
#[type_name("harvest.LaserScanRequest.v1")]
pub struct LaserScanRequest {
    /// Sequence number, capture and publish stamps (ns, stack clock); see [`Header`].
    pub header: Header,
    /// Chosen by the requester; echoed in the [`LaserScanResult`].
    pub request_seq: u32,
    /// The apple to scan, as perception numbers it.
    pub apple_id: u32,
    /// Rough target position from the ToF camera, in the ToF colour-camera frame (metres).
    pub rough_position_in_camera_m: [f64; 3],
    /// Rough apple radius from the ToF camera, metres.
    pub rough_radius_m: f64,
}

/// How a scan ended (code in [`LaserScanResult::status`]).
#[repr(u8)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, crate::WireEnum)]
pub enum LaserScanStatus {
    /// A position was measured.
    Ok = 0,
    /// No laser line was found in the images.
    NoLaserLine = 1,
    /// The target is out of the slide's view or reach.
    OutOfReach = 2,
    /// The ALACS device (or the scan set-up) failed.
    DeviceError = 3,
}

/// The answer to one [`LaserScanRequest`] (`laser/scan_result`).
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
#[type_name("harvest.LaserScanResult.v1")]
pub struct LaserScanResult {
    /// `capture_ns` is when the scan finished; see [`Header`].
    pub header: Header,
    /// The request's `request_seq`.
    pub request_seq: u32,
    /// The request's `apple_id`.
    pub apple_id: u32,
    /// How the scan ended.
    pub status: WireCode<LaserScanStatus>,
    /// Valid entries of `candidates_in_camera_m` and `candidate_scores`.
    pub candidate_count: u8,
    /// Index (into the candidates listed) of the candidate the selection of [alacs sec. 3] picks.
    pub selected: u8,
    /// Zero; keeps the following fields aligned.
    pub _reserved: [u8; 5],
    /// Final position in the ToF colour-camera frame: the sphere fitted to all stripes when at
    /// least 3 agree, else the selected candidate; the request's rough position on failure.
    pub position_in_camera_m: [f64; 3],
    /// Per-image candidates that produced a position, in scan order (`candidate_count` valid).
    pub candidates_in_camera_m: [[f64; 3]; MAX_SCAN_CANDIDATES],
    /// Each candidate's predicted standard error, metres.
    pub candidate_scores: [f64; MAX_SCAN_CANDIDATES],
    /// Time from the request to the result, ns.
    pub scan_duration_ns: u64,
}
