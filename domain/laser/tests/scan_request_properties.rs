//! Property test of what the laser process reads from shared memory: scan
//! requests of any content (NaN or infinite rough positions, absurd radii, garbage sequence
//! numbers) answered by the transport-free `ScanService` on the in-process rendered ALACS unit.
//! The service answers every request: a result, or an error with its status code, never a
//! panic; a successful result is finite and names at most its candidate capacity.
//!
//! Requests are filled through their raw bytes (`Payload` makes every bit pattern a valid
//! value), so the property holds whatever the field types of the payload become.

use harvest_hw::alacs::{ALACS_FROM_TOF_CAMERA, AlacsUnit, alacs_camera_intrinsics};
use harvest_ipc::Payload;
use harvest_ipc::camera_model::CameraIntrinsics;
use harvest_ipc::payloads::laser_scan::MAX_SCAN_CANDIDATES;
use harvest_ipc::payloads::{LaserScanRequest, LaserScanResult};
use harvest_laser::ScanService;
use harvest_sim::alacs::{AlacsScene, AppleSphere, RenderedAlacs, RenderedAlacsConfig};
use proptest::prelude::*;

/// Cases: a request near the apple runs a whole scan (five rendered images).
const CASES: u32 = 12;

const WILD: &[u64] = &[
    0x7ff8_0000_0000_0000, // NaN
    0x7ff0_0000_0000_0000, // +inf
    0xfff0_0000_0000_0000, // -inf
    0,
    0x8000_0000_0000_0000, // -0.0
    0x7fef_ffff_ffff_ffff, // f64::MAX
    1,
    u64::MAX,
    0x3fe0_0000_0000_0000, // 0.5
    0xbfe0_0000_0000_0000, // -0.5
    0x3fa4_7ae1_47ae_147b, // 0.04 (an apple radius)
];

fn wild_u64() -> impl Strategy<Value = u64> {
    prop_oneof![
        3 => prop::sample::select(WILD),
        1 => any::<u64>(),
    ]
}

fn bytes_of<T: Payload>(value: &mut T) -> &mut [u8] {
    // SAFETY: `value` is a valid, uniquely borrowed `T` of `size_of::<T>()` bytes, and every bit
    // pattern is a valid `T` (the `Payload` contract), so any bytes written leave a valid `T`.
    unsafe {
        std::slice::from_raw_parts_mut((value as *mut T).cast::<u8>(), std::mem::size_of::<T>())
    }
}

/// Half the ALACS camera's resolution, same field of view, to keep the scans quick.
fn camera() -> CameraIntrinsics {
    let mut intrinsics = alacs_camera_intrinsics();
    intrinsics.width_px = 720;
    intrinsics.height_px = 540;
    intrinsics.fx_px *= 0.5;
    intrinsics.fy_px *= 0.5;
    intrinsics.cx_px = 359.5;
    intrinsics.cy_px = 269.5;
    intrinsics
}

const APPLE_IN_ALACS_M: [f64; 3] = [-0.03, 0.04, 0.9];

/// A well-formed request for the rendered apple (in the ToF colour camera frame).
fn good_request() -> LaserScanRequest {
    let mut request = LaserScanRequest::default();
    request.header.msg_seq = 1;
    request.request_seq = 1;
    request.apple_id = 7;
    let centre = ALACS_FROM_TOF_CAMERA.inverse().apply(APPLE_IN_ALACS_M);
    request.rough_position_in_camera_m = [centre[0] + 0.004, centre[1] - 0.003, centre[2] + 0.015];
    request.rough_radius_m = 0.04;
    request
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(CASES))]

    #[test]
    fn scan_requests_of_any_content_are_answered(
        garbage in prop::collection::vec(wild_u64(), 0..8),
        edits in prop::collection::vec((any::<prop::sample::Index>(), wild_u64()), 0..4),
    ) {
        let config = RenderedAlacsConfig::default();
        let extrinsics = config.extrinsics;
        let scene = AlacsScene {
            apples: vec![AppleSphere {
                centre_in_camera_m: APPLE_IN_ALACS_M,
                radius_m: 0.04,
                rgb: [150, 30, 25],
            }],
            background_depth_m: Some(1.3),
            ..AlacsScene::default()
        };
        let mut unit = RenderedAlacs::new(camera(), config, scene).expect("unit");
        let mut service = ScanService::new(extrinsics, unit.intrinsics(), ALACS_FROM_TOF_CAMERA)
            .expect("service");
        let mut request = harvest_ipc::payload::boxed_zeroed::<LaserScanRequest>();
        *request = good_request();
        let bytes = bytes_of(&mut *request);
        for (chunk, value) in bytes.chunks_mut(8).zip(garbage.iter()) {
            chunk.copy_from_slice(&value.to_le_bytes()[..chunk.len()]);
        }
        let slots = bytes.len() / 8;
        for (at, value) in &edits {
            let start = at.index(slots) * 8;
            bytes[start..start + 8].copy_from_slice(&value.to_le_bytes());
        }
        let mut result = harvest_ipc::payload::boxed_zeroed::<LaserScanResult>();
        match service.answer(&mut unit, &request, &mut result, &mut || {}) {
            Ok(scan) => {
                prop_assert!(scan.centre_in_camera_m.iter().all(|c| c.is_finite()), "{scan:?}");
                prop_assert!(
                    result.position_in_camera_m.iter().all(|c| c.is_finite()),
                    "{result:?}"
                );
                prop_assert!(usize::from(result.candidate_count) <= MAX_SCAN_CANDIDATES);
            }
            Err(error) => {
                prop_assert!(!error.to_string().is_empty());
                let _ = error.status();
            }
        }
    }
}
