//! The detector and localization on rendered frames where every apple is over-exposed and many
//! sit behind leaves: every reported apple must be an apple, localized on it, never on a leaf
//! in front of it.

use harvest_ipc::payloads::AppleDetections;
use harvest_perception::PerceptionConfig;
use harvest_perception::calibration::{Calibration, CameraCalibration};
use harvest_perception::node::PerceptionNode;
use harvest_sim::render_rgbd::label;
use harvest_sim::{Scenario, World};

use crate::perception::frame::{FrameRenderer, zeroed_frame};
use crate::perception::truth::{FrameApple, TruthMeter, count_box_overlap};

#[test]
fn over_exposed_apples_behind_leaves_are_localized_on_the_apple_not_the_leaf() {
    let mut scenario = Scenario::preset("default").expect("default");
    scenario.failures.camera_overexposure = 1.0;
    scenario.failures.heavy_occlusion = 0.5;
    let mut renderer = FrameRenderer::new(&scenario.camera).expect("renderer");
    let robot_from_color = renderer.robot_from_color();
    let meter = TruthMeter::new(renderer.color_intrinsics(), robot_from_color);
    let mut config = PerceptionConfig::default();
    config.laser.enabled = false;
    let calibration = Calibration {
        camera: CameraCalibration {
            robot_from_camera: robot_from_color,
        },
    };
    let mut node = PerceptionNode::new(config, calibration);
    let mut frame = zeroed_frame();
    let mut out = Box::<AppleDetections>::default();
    let mut labels = vec![0u32; meter.pixel_count()];
    let mut truth: Vec<FrameApple> = Vec::new();
    let (mut reported, mut half_visible, mut found_half_visible) = (0, 0, 0);
    for seed in 1..=3_u64 {
        let world = World::generate(&scenario, seed).expect("world");
        renderer.render(&world, seed, &mut frame).expect("render");
        renderer.render_labels(&world, &mut labels).expect("labels");
        meter.measure(&world, &labels, &mut truth);
        node.process(&frame, &mut out).expect("process");
        let mut overlap = vec![0u64; truth.len()];
        let mut found = vec![false; truth.len()];
        for apple in out.apples.as_slice() {
            reported += 1;
            overlap.fill(0);
            count_box_overlap(&labels, meter.width_px(), apple.box_px, &mut overlap);
            // The apple the box covers most.
            let (id, &pixels) = overlap
                .iter()
                .enumerate()
                .max_by_key(|(_, count)| **count)
                .expect("apples");
            assert!(
                pixels > 0,
                "seed {seed}: a detection with no apple pixel in its box"
            );
            // Its leaf pixels do not outnumber its apple pixels (a box drawn on a leaf would).
            let [u0, v0, w, h] = apple.box_px.map(|x| x as usize);
            let width = meter.width_px();
            let leaf_px = (v0..v0 + h)
                .flat_map(|v| labels[v * width + u0..v * width + u0 + w].iter())
                .filter(|&&l| l == label::LEAF)
                .count() as u64;
            assert!(
                leaf_px <= pixels,
                "seed {seed}: box {:?} holds {leaf_px} leaf and {pixels} apple pixels",
                apple.box_px
            );
            // And its centre is the apple's, within one radius (on a leaf in front it would be
            // a radius or more too near).
            let t = &truth[id];
            let error_m = (0..3)
                .map(|k| (apple.position_in_robot_m[k] - t.center_in_robot_m[k]).powi(2))
                .sum::<f64>()
                .sqrt();
            assert!(
                error_m < t.radius_m,
                "seed {seed}: apple {id} localized {:.1} mm off",
                error_m * 1e3
            );
            found[id] = true;
        }
        for (t, apple) in truth.iter().enumerate() {
            if apple.visible_fraction() >= 0.5 {
                half_visible += 1;
                found_half_visible += usize::from(found[t]);
            }
        }
    }
    assert!(reported > 20, "{reported} apples reported");
    // Blown-out apples are still found, from their saturated blobs alone (no colour). A floor,
    // not a target: 23 of 46 here. Most misses are small blobs of mostly hidden apples whose
    // few, glare-noisy depth samples fail the curvature check.
    assert!(
        found_half_visible * 10 >= half_visible * 4,
        "found {found_half_visible} of {half_visible} apples at least half visible"
    );
}
