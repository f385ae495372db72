//! ALACS laser scans: perception asks for a scan of one apple, the laser process answers.

use crate::header::Header;
use iceoryx2::prelude::ZeroCopySend;
use serde::{Deserialize, Serialize};

/// Images per interval scan (paper: 5 images at 1 cm steps).
pub const MAX_SCAN_CANDIDATES: usize = 5;

#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend, Serialize, Deserialize)]
#[type_name("harvest.LaserScanRequest.v1")]
pub struct LaserScanRequest {
    pub header: Header,
    pub request_seq: u32,
    pub apple_id: u32,
    /// Rough target position from the ToF camera, in the ToF colour-camera frame (metres).
    pub rough_position_in_camera_m: [f64; 3],
    pub rough_radius_m: f64,
}

crate::serde_payload!(
    LaserScanRequest,
    "harvest.LaserScanRequest",
    1,
    "encoding bincode2-fixint-le: header: {msg_seq:u64, capture_ns:u64, publish_ns:u64}; \
request_seq:u32; apple_id:u32; rough_position_in_camera_m:[f64;3]; rough_radius_m:f64"
);

#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend, Serialize, Deserialize)]
#[type_name("harvest.LaserScanResult.v1")]
pub struct LaserScanResult {
    pub header: Header,
    pub request_seq: u32,
    pub apple_id: u32,
    /// 0 ok, 1 no laser line found, 2 target out of the slide's view or reach, 3 device error.
    pub status: u8,
    pub candidate_count: u8,
    /// Index (into the candidates listed) of the candidate the paper's selection picks.
    pub selected: u8,
    pub _reserved: [u8; 5],
    /// Final position in the ToF colour-camera frame: the sphere fitted to all stripes when at
    /// least 3 agree, else the selected candidate; the request's rough position on failure.
    pub position_in_camera_m: [f64; 3],
    /// Per-image candidates that produced a position, in scan order (`candidate_count` valid).
    pub candidates_in_camera_m: [[f64; 3]; MAX_SCAN_CANDIDATES],
    /// Each candidate's predicted standard error, metres.
    pub candidate_scores: [f64; MAX_SCAN_CANDIDATES],
    pub scan_duration_ns: u64,
}

crate::serde_payload!(
    LaserScanResult,
    "harvest.LaserScanResult",
    1,
    "encoding bincode2-fixint-le: header: {msg_seq:u64, capture_ns:u64, publish_ns:u64}; \
request_seq:u32; apple_id:u32; status:u8; candidate_count:u8; selected:u8; _reserved:[u8;5]; \
position_in_camera_m:[f64;3]; candidates_in_camera_m:[[f64;3];5]; candidate_scores:[f64;5]; \
scan_duration_ns:u64"
);
