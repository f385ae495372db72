//! Property tests of what perception reads from outside. From shared memory:
//! camera frames
//! whose metadata holds any bit pattern (NaN or zero focal lengths, sizes that do not match the
//! buffers, rotations that are not rotations), LiDAR clouds of any content and point count, and
//! laser scan results of any content, through the transport-free `PerceptionNode` and the
//! LiDAR depth fusion as the perception process wires them. From files: the configuration and
//! the calibration with values replaced by anything, lines dropped or doubled and bytes
//! changed, refused with an error naming the file or used on a frame. Nothing may panic; a
//! frame is processed or rejected with an error, and every published detection is finite.
//!
//! Payloads are filled through their raw bytes (`Payload` makes every bit pattern a valid
//! value), so the properties hold whatever the field types of the payloads become.

use harvest_ipc::Payload;
use harvest_ipc::payloads::{
    AppleDetections, LaserScanResult, PointCloud, PointCloudMeta, RgbdFrame, RgbdFrameMeta,
};
use harvest_perception::calibration::Calibration;
use harvest_perception::camera_setup::CameraSetup;
use harvest_perception::config_file::{DEFAULT_CONFIG, parse_config};
use harvest_perception::depth_source::FusedDepth;
use harvest_perception::node::PerceptionNode;
use harvest_perception::pipeline::PerceptionConfig;
use harvest_perception::synthetic::SyntheticScene;
use harvest_test_support::toml_mutation::{mutate_toml, toml_edit};
use proptest::prelude::*;
use std::sync::OnceLock;

/// Cases per property: each processes two or three full 1920x1080 frames (tens of ms each).
const CASES: u32 = 16;

/// Bit patterns that break numeric code (as in the other shared-memory properties).
const WILD: &[u64] = &[
    0x7ff8_0000_0000_0000, // NaN
    0x7ff0_0000_0000_0000, // +inf
    0xfff0_0000_0000_0000, // -inf
    0,
    0x8000_0000_0000_0000, // -0.0
    0x7fef_ffff_ffff_ffff, // f64::MAX
    1,
    0xffff_ffff,
    u64::MAX,
    0x0000_0438_0000_0780, // u32 1920, 1080 (a plausible image size)
    0x0000_01e0_0000_0280, // u32 640, 480
    0x0000_0001_0000_0001, // u32 1, 1
    0x3ff0_0000_0000_0000, // 1.0
    0x408f_4000_0000_0000, // 1000.0 (a focal length)
    0x4073_b000_0000_0000, // 315.0
];

fn wild_u64() -> impl Strategy<Value = u64> {
    prop_oneof![
        3 => prop::sample::select(WILD),
        1 => any::<u64>(),
    ]
}

/// The raw bytes of a payload (every bit pattern of them is a valid value).
fn bytes_of<T: Payload>(value: &mut T) -> &mut [u8] {
    // SAFETY: `value` is a valid, uniquely borrowed `T` of `size_of::<T>()` bytes, and every bit
    // pattern is a valid `T` (the `Payload` contract), so any bytes written leave a valid `T`.
    unsafe {
        std::slice::from_raw_parts_mut((value as *mut T).cast::<u8>(), std::mem::size_of::<T>())
    }
}

/// Writes `values` (8 bytes each, repeated) over `bytes`.
fn fill(bytes: &mut [u8], values: &[u64]) {
    if values.is_empty() {
        return;
    }
    for (chunk, value) in bytes.chunks_mut(8).zip(values.iter().cycle()) {
        for (byte, source) in chunk.iter_mut().zip(value.to_le_bytes()) {
            *byte = source;
        }
    }
}

/// Overwrites the aligned 8-byte slots `edits` names in `bytes`.
fn edit(bytes: &mut [u8], edits: &[(prop::sample::Index, u64)]) {
    let slots = (bytes.len() / 8).max(1);
    for (at, value) in edits {
        let start = at.index(slots) * 8;
        for (byte, source) in bytes[start..].iter_mut().zip(value.to_le_bytes()) {
            *byte = source;
        }
    }
}

struct Rig {
    calibration: Calibration,
    frame: Box<RgbdFrame>,
}

/// The simulated camera's rig and one rendered orchard frame (made once).
fn rig() -> &'static Rig {
    static RIG: OnceLock<Rig> = OnceLock::new();
    RIG.get_or_init(|| {
        let calibration = Calibration::parse(
            include_str!("../../../sim/camera_calibration.toml"),
            "sim/camera_calibration.toml",
        )
        .expect("calibration");
        let cameras = CameraSetup::tl460_simulated(calibration.camera.robot_from_camera);
        let rendered = SyntheticScene::orchard(&cameras, 4, 7).render(&cameras);
        let mut frame = harvest_ipc::payload::boxed_zeroed::<RgbdFrame>();
        frame.header.msg_seq = 1;
        frame.header.capture_ns = 1_000_000_000;
        frame.meta = RgbdFrameMeta {
            rgb_intrinsics: cameras.color,
            depth_intrinsics: cameras.depth,
            color_from_depth: cameras.color_from_depth,
            exposure_us: 1000,
            flags: 0,
        };
        frame.rgb.copy_from_slice(&rendered.rgb);
        frame.depth_mm.copy_from_slice(&rendered.depth_mm);
        Rig { calibration, frame }
    })
}

/// A copy of the rendered frame (in a fresh heap box, as a loaned sample).
fn frame_copy() -> Box<RgbdFrame> {
    let base = &rig().frame;
    let mut frame = harvest_ipc::payload::boxed_zeroed::<RgbdFrame>();
    frame.header = base.header;
    frame.meta = base.meta;
    frame.rgb.copy_from_slice(&base.rgb);
    frame.depth_mm.copy_from_slice(&base.depth_mm);
    frame
}

/// The header and metadata bytes of a frame (everything but the pixel buffers).
fn frame_head(frame: &mut RgbdFrame) -> &mut [u8] {
    let end = std::mem::offset_of!(RgbdFrame, meta) + std::mem::size_of::<RgbdFrameMeta>();
    &mut bytes_of(frame)[..end]
}

/// Every detection published is finite.
fn check_detections(out: &AppleDetections) -> Result<(), TestCaseError> {
    for apple in out.apples.iter() {
        prop_assert!(
            apple.position_in_robot_m.iter().all(|c| c.is_finite())
                && apple.position_in_camera_m.iter().all(|c| c.is_finite())
                && apple.radius_m.is_finite(),
            "non-finite detection {apple:?}"
        );
    }
    Ok(())
}

/// One frame through the node as the perception process runs it: scan results first, then the
/// cloud into the fused depth, then the frame (with the fused depth when there is one).
fn run_frame(
    node: &mut PerceptionNode,
    fused: &mut FusedDepth,
    frame: &RgbdFrame,
    cloud: Option<&PointCloud>,
    scan_result: Option<&LaserScanResult>,
) -> Result<(), TestCaseError> {
    if let Some(result) = scan_result {
        let _ = node.handle_scan_result(result);
    }
    if let Some(cloud) = cloud
        && let Err(error) = fused.update(&frame.meta, cloud.valid_points())
    {
        prop_assert!(!error.to_string().is_empty());
    }
    let depth = fused.depth_for(&frame.meta);
    let mut out = harvest_ipc::payload::boxed_zeroed::<AppleDetections>();
    match node.process_with_depth(frame, depth, &mut out) {
        Ok(_) => check_detections(&out)?,
        Err(error) => {
            prop_assert!(!error.to_string().is_empty());
            prop_assert!(out.apples.is_empty(), "a rejected frame publishes no apple");
        }
    }
    for request in node.scan_requests() {
        prop_assert!(
            request
                .rough_position_in_camera_m
                .iter()
                .all(|c| c.is_finite()),
            "non-finite scan request {request:?}"
        );
    }
    Ok(())
}

/// Perception asking a laser scan for every apple it sees, so scan results have scans to answer.
fn config() -> PerceptionConfig {
    parse_config(
        "[laser]\nmax_visible_fraction = 1.0\nmin_position_confidence = 1.0\n",
        "test config",
    )
    .expect("config")
}

fn new_node() -> (PerceptionNode, FusedDepth) {
    (
        PerceptionNode::new(config(), rig().calibration),
        FusedDepth::new(harvest_lidar::CAD_CAMERA_FROM_LIDAR),
    )
}

/// The bench itself works: the rendered frame gives apples and scan requests, so the properties
/// below judge a pipeline that really detects and asks for scans.
#[test]
fn the_rendered_frame_gives_apples() {
    let (mut node, _) = new_node();
    let mut out = harvest_ipc::payload::boxed_zeroed::<AppleDetections>();
    node.process(&frame_copy(), &mut out).expect("a good frame");
    assert!(!out.apples.is_empty(), "no apple in the rendered frame");
    assert!(!node.scan_requests().is_empty(), "no laser scan asked for");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(CASES))]

    /// Frames whose header and metadata are wholly garbage, or the real ones with a few slots
    /// overwritten; each follows a good frame (so the node rebuilds its rig for the bad one)
    /// and is followed by one (so it recovers).
    #[test]
    fn frames_with_any_metadata_never_panic(
        garbage in prop::collection::vec(wild_u64(), 0..24),
        edits in prop::collection::vec((any::<prop::sample::Index>(), wild_u64()), 1..6),
    ) {
        let (mut node, mut fused) = new_node();
        run_frame(&mut node, &mut fused, &frame_copy(), None, None)?;
        let mut bad = frame_copy();
        if garbage.is_empty() {
            edit(frame_head(&mut bad), &edits);
        } else {
            fill(frame_head(&mut bad), &garbage);
        }
        run_frame(&mut node, &mut fused, &bad, None, None)?;
        run_frame(&mut node, &mut fused, &frame_copy(), None, None)?;
        prop_assert_eq!(node.frames_processed(), 3);
    }

    /// LiDAR clouds of any content and any point count, fused into the depth of good and bad
    /// frames.
    #[test]
    fn clouds_of_any_content_never_panic(
        cloud_values in prop::collection::vec(wild_u64(), 1..32),
        point_count in prop_oneof![Just(u32::MAX), 0u32..2000, any::<u32>()],
        meta_edits in prop::collection::vec((any::<prop::sample::Index>(), wild_u64()), 0..3),
    ) {
        let (mut node, mut fused) = new_node();
        let mut cloud = harvest_ipc::payload::boxed_zeroed::<PointCloud>();
        fill(bytes_of(&mut *cloud), &cloud_values);
        let count_at = std::mem::offset_of!(PointCloud, meta)
            + std::mem::offset_of!(PointCloudMeta, point_count);
        bytes_of(&mut *cloud)[count_at..count_at + 4].copy_from_slice(&point_count.to_le_bytes());
        let mut frame = frame_copy();
        edit(frame_head(&mut frame), &meta_edits);
        run_frame(&mut node, &mut fused, &frame, Some(&cloud), None)?;
        run_frame(&mut node, &mut fused, &frame_copy(), Some(&cloud), None)?;
    }

    /// Laser scan results of any content (unknown status codes, candidate counts past their
    /// arrays, NaN positions), addressed to a scan the node asked for or to none.
    #[test]
    fn scan_results_of_any_content_never_panic(
        results in prop::collection::vec(
            (prop::collection::vec(wild_u64(), 1..16), any::<bool>()), 1..6),
    ) {
        let (mut node, mut fused) = new_node();
        run_frame(&mut node, &mut fused, &frame_copy(), None, None)?;
        let requests: Vec<_> = node.scan_requests().to_vec();
        for (values, answer_a_request) in &results {
            let mut result = harvest_ipc::payload::boxed_zeroed::<LaserScanResult>();
            fill(bytes_of(&mut *result), values);
            if *answer_a_request && let Some(request) = requests.first() {
                // Keep the garbage, but address it to a scan the node is waiting for.
                result.request_seq = request.request_seq;
                result.apple_id = request.apple_id;
            }
            run_frame(&mut node, &mut fused, &frame_copy(), None, Some(&result))?;
        }
    }

    /// The documented configuration and the simulated camera's calibration, mutated: refused
    /// with an error naming the file, or a node that processes frames.
    #[test]
    fn mutated_config_and_calibration_are_refused_by_name_or_used(
        config_edits in prop::collection::vec(toml_edit(), 0..4),
        calibration_edits in prop::collection::vec(toml_edit(), 0..3),
    ) {
        let config = match parse_config(&mutate_toml(DEFAULT_CONFIG, &config_edits), "mutated.toml") {
            Ok(config) => config,
            Err(error) => {
                prop_assert!(error.to_string().contains("mutated.toml"), "{error}");
                return Ok(());
            }
        };
        let text = mutate_toml(
            include_str!("../../../sim/camera_calibration.toml"),
            &calibration_edits,
        );
        let calibration = match Calibration::parse(&text, "calibration.toml") {
            Ok(calibration) => calibration,
            Err(error) => {
                prop_assert!(error.to_string().contains("calibration.toml"), "{error}");
                return Ok(());
            }
        };
        let mut node = PerceptionNode::new(config, calibration);
        let mut fused = FusedDepth::new(harvest_lidar::CAD_CAMERA_FROM_LIDAR);
        run_frame(&mut node, &mut fused, &frame_copy(), None, None)?;
    }
}
