//! Detections for the harvesting evaluation: the simulator's true apples seen through the ToF
//! camera's depth-noise model, instead of perception's real pipeline (which `harvest eval
//! perception` evaluates on rendered frames). This isolates the harvesting loop (assignment,
//! coordination, arm control, vacuum) from perception failures; Table 3's perception causes
//! (exposure, occlusion, clusters) are therefore not reproduced here.
//!
//! Model: every apple still on its stem and inside the camera's working range is detected. Its
//! centre is displaced along the camera ray by a normal range error of one standard deviation
//! `depth_noise_mm + depth_noise_fraction * depth` (the camera's per-pixel depth model,
//! `CameraConfig::depth_sigma_mm`), times `overexposed_depth_noise_gain` for an over-exposed
//! apple, times the evaluation's `--detection-noise` scale. A set is captured every
//! [`DetectionModel::period_s`] and delivered [`DetectionModel::latency_s`] later.

use harvest_ipc::payloads::{AppleDetection, AppleDetections, DepthSourceCode, LocalizationMethod};
use harvest_sim::orchard::{AppleState, World};
use rand::Rng;
use rand::rngs::SmallRng;
use rand_distr::{Distribution, StandardNormal};

/// When and how detection sets are produced.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DetectionModel {
    /// Time between captured sets, s (choice: 0.2 s, a 5 Hz perception throughput).
    pub period_s: f64,
    /// Capture-to-delivery latency, s (choice: 0.1 s of perception processing).
    pub latency_s: f64,
    /// Scale of the depth-noise model (0 = exact centres).
    pub noise_scale: f64,
}

impl Default for DetectionModel {
    fn default() -> Self {
        Self {
            period_s: 0.2,
            latency_s: 0.1,
            noise_scale: 1.0,
        }
    }
}

/// One detection set of `world` as captured at `capture_ns`.
pub fn detect(
    world: &World,
    capture_ns: u64,
    seq: u64,
    model: &DetectionModel,
    rng: &mut SmallRng,
) -> AppleDetections {
    let camera = &world.scenario().camera;
    let robot_from_camera = world.robot_from_camera();
    let camera_from_robot = robot_from_camera.inverse();
    let mut set = AppleDetections {
        source_frame_seq: seq,
        source_capture_ns: capture_ns,
        ..AppleDetections::default()
    };
    set.header.msg_seq = seq;
    set.header.capture_ns = capture_ns;
    for apple in world.apples() {
        if apple.state != AppleState::OnTree {
            continue;
        }
        let in_camera = camera_from_robot.apply(apple.center_in_robot_m);
        let range_m = in_camera.iter().map(|c| c * c).sum::<f64>().sqrt();
        if !(camera.range_m[0]..=camera.range_m[1]).contains(&in_camera[2]) || range_m <= 0.0 {
            continue;
        }
        let gain = if apple.overexposed {
            camera.overexposed_depth_noise_gain
        } else {
            1.0
        };
        let sigma_m = camera.depth_sigma_mm(in_camera[2] * 1e3) * 1e-3 * gain * model.noise_scale;
        let normal: f64 = StandardNormal.sample(rng);
        let scale = 1.0 + normal * sigma_m / range_m;
        let noisy = in_camera.map(|c| c * scale);
        let detection = AppleDetection {
            apple_id: apple.id.0,
            method: LocalizationMethod::ClusterCentroid.into(),
            depth_source: DepthSourceCode::Tof.into(),
            _reserved: [0; 2],
            position_in_camera_m: noisy,
            position_in_robot_m: robot_from_camera.apply(noisy),
            radius_m: apple.radius_m,
            confidence: 1.0,
            box_px: [0; 4],
            visible_px: 0,
        };
        if set.apples.push(detection).is_err() {
            tracing::debug!(
                capture_ns,
                "detection set full: further apples not reported"
            );
            break;
        }
    }
    // Keep the stream's randomness independent of how many apples were seen.
    let _: u64 = rng.random();
    set
}

#[cfg(test)]
mod tests {
    use super::*;
    use harvest_sim::scenario::Scenario;
    use rand::SeedableRng;

    #[test]
    fn exact_without_noise_and_spread_as_the_camera_model_with_it() {
        let scenario = Scenario::preset("ideal").expect("ideal");
        let world = World::generate(&scenario, 3).expect("world");
        let mut rng = SmallRng::seed_from_u64(1);
        let exact = detect(
            &world,
            5,
            1,
            &DetectionModel {
                noise_scale: 0.0,
                ..DetectionModel::default()
            },
            &mut rng,
        );
        assert_eq!(exact.apples.len(), world.apples().len());
        for (d, a) in exact.apples.iter().zip(world.apples()) {
            let e = (0..3)
                .map(|i| (d.position_in_robot_m[i] - a.center_in_robot_m[i]).powi(2))
                .sum::<f64>()
                .sqrt();
            assert!(e < 1e-9, "{e}");
            assert_eq!(d.radius_m, a.radius_m);
        }
        // With noise: the error's standard deviation matches the model within 10 %.
        let model = DetectionModel::default();
        let (mut sum2, mut expected2, mut n) = (0.0, 0.0, 0.0);
        let camera_from_robot = world.robot_from_camera().inverse();
        for k in 0..400 {
            let set = detect(&world, 5, k, &model, &mut rng);
            for (d, a) in set.apples.iter().zip(world.apples()) {
                let e2: f64 = (0..3)
                    .map(|i| (d.position_in_robot_m[i] - a.center_in_robot_m[i]).powi(2))
                    .sum();
                let z_mm = camera_from_robot.apply(a.center_in_robot_m)[2] * 1e3;
                sum2 += e2;
                expected2 += (scenario.camera.depth_sigma_mm(z_mm) * 1e-3).powi(2);
                n += 1.0;
            }
        }
        let ratio = (sum2 / n).sqrt() / (expected2 / n).sqrt();
        assert!((0.9..1.1).contains(&ratio), "{ratio}");
    }
}
