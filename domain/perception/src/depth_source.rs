//! Where perception takes its depth from: the ToF camera's depth image (`tof`, the default) or
//! the LiDAR cloud fused into that image's geometry (`lidar_fused`, [fusion sec. II-B,
//! eq. 1-2] via [`harvest_lidar::fusion::Fusion`]).
//!
//! The fused depth image has the ToF depth image's layout (640x480 depth intrinsics, millimetres,
//! 0 = no point), so the pipeline (registration into the colour image, the estimators) runs on it
//! unchanged: [`FusedDepth`] owns that image, allocated once per camera geometry and rewritten in
//! place for every new cloud, and the node reads it through
//! [`crate::node::PerceptionNode::process_with_depth`] beside the frame in shared memory (the
//! 6.8 MB frame is never copied).
//!
//! Frames that arrive before the first cloud (or after the camera geometry changed, until the next
//! cloud) are localized from the ToF depth and counted ([`FusedDepthCounters::tof_fallback_frames`]);
//! their detections carry depth source code `Tof`, the fused ones `LidarFused` (the method code
//! names the estimator in both).
//!
//! Frames from a colour-only camera (a GigE Vision camera: `RgbdFrameMeta::FLAG_COLOR_ONLY`) have
//! no ToF depth: their depth grid is a pinhole view through the colour camera that the cloud is
//! fused onto the same way, and until the first cloud they are refused
//! ([`crate::pipeline::PerceptionSetupError::NoDepthSource`], counted in
//! [`FusedDepthCounters::frames_without_depth`]).

use crate::noise_model::DepthNoiseModel;
use harvest_hw::lidar::LidarSpec;
use harvest_ipc::camera_model::RigidTransform;
use harvest_ipc::payloads::{LidarPoint, RgbdFrameMeta};
use harvest_lidar::fusion::{Fusion, FusionConfig, FusionError, FusionStats};
use serde::{Deserialize, Serialize};

/// The depth image perception localizes from (config key `depth_source`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DepthSource {
    /// The ToF camera's depth image of each frame.
    #[default]
    Tof,
    /// The newest `lidar/points` cloud fused into the ToF depth image's geometry.
    LidarFused,
}

impl std::str::FromStr for DepthSource {
    type Err = String;

    /// The config-file spelling (`lidar_fused`) or the command line's (`lidar-fused`).
    fn from_str(text: &str) -> Result<Self, Self::Err> {
        [Self::Tof, Self::LidarFused]
            .into_iter()
            .find(|source| source.name() == text.replace('-', "_"))
            .ok_or_else(|| format!("unknown depth source {text:?} (tof or lidar-fused)"))
    }
}

impl DepthSource {
    /// The config-file spelling.
    pub fn name(self) -> &'static str {
        match self {
            Self::Tof => "tof",
            Self::LidarFused => "lidar_fused",
        }
    }

    /// Apples whose confidence (mask times position) is below this are not reported. The ToF
    /// camera's dense depth gives most apples a sphere fit (0.25 drops the fallbacks of
    /// few-point fragments); a 1 s LiDAR window puts some 10-300 points on an apple, so many of
    /// them take the median-depth fallback (confidence <= 0.3 times the mask's), which 0.05
    /// keeps: more apples at a larger error (`harvest eval perception` reports both for the
    /// LiDAR-fused variants).
    pub fn min_output_confidence(self) -> f32 {
        match self {
            Self::Tof => 0.25,
            Self::LidarFused => 0.05,
        }
    }

    /// The noise scale of this source's depth samples: the TL460's datasheet accuracy
    /// (+/-(4 mm + 0.25 % of depth)) or the Mid-70's range error (Table II: 2 cm at any range),
    /// each taken as one sigma, as the simulator does.
    pub fn noise_model(self) -> DepthNoiseModel {
        match self {
            Self::Tof => DepthNoiseModel::TL460,
            Self::LidarFused => DepthNoiseModel {
                base_m: LidarSpec::mid70().range_sigma_m,
                fraction_of_depth: 0.0,
            },
        }
    }
}

/// Counters of the fused depth source.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FusedDepthCounters {
    /// Clouds fused into a depth image.
    pub clouds_fused: u64,
    /// Clouds that could not be fused (empty, all non-finite); the previous depth is kept.
    pub clouds_rejected: u64,
    /// Frames localized from the ToF depth because no fused depth was available yet.
    pub tof_fallback_frames: u64,
    /// Colour-only frames (no ToF depth to fall back on) that came before any fused depth:
    /// perception refuses them.
    pub frames_without_depth: u64,
}

/// The LiDAR-fused depth image, in the ToF depth image's geometry.
pub struct FusedDepth {
    camera_from_lidar: RigidTransform,
    /// The fusion and the frame geometry it was built for.
    fusion: Option<(RgbdFrameMeta, Fusion)>,
    /// Fused depth, mm, the depth image's layout; valid when `valid`.
    depth_mm: Vec<u16>,
    valid: bool,
    counters: FusedDepthCounters,
}

impl FusedDepth {
    /// `camera_from_lidar`: the extrinsic `T_L^C`, LiDAR frame -> colour camera frame (from
    /// `harvest calibrate lidar-camera --output`, or the simulated unit's).
    pub fn new(camera_from_lidar: RigidTransform) -> Self {
        Self {
            camera_from_lidar,
            fusion: None,
            depth_mm: Vec::new(),
            valid: false,
            counters: FusedDepthCounters::default(),
        }
    }

    pub fn counters(&self) -> FusedDepthCounters {
        self.counters
    }

    /// Fuses a cloud (LiDAR frame) into the depth image of frames with geometry `meta`
    /// (eq. 1-2). The fusion and its image are rebuilt only when `meta` changes. A cloud that
    /// cannot be fused is counted and returned as the error; the previous depth stays in use.
    pub fn update(
        &mut self,
        meta: &RgbdFrameMeta,
        points: &[LidarPoint],
    ) -> Result<FusionStats, FusionError> {
        let fusion = match self.fusion.take() {
            Some((built_for, fusion)) if built_for == *meta => fusion,
            _ => {
                self.valid = false;
                let fusion = Fusion::new(
                    FusionConfig::for_tof_depth(meta, self.camera_from_lidar)
                        .with_range_noise(LidarSpec::mid70().range_sigma_m),
                )?;
                let pixels = meta.depth_intrinsics.width_px as usize
                    * meta.depth_intrinsics.height_px as usize;
                self.depth_mm.clear();
                self.depth_mm.resize(pixels, 0);
                fusion
            }
        };
        let (_, fusion) = self.fusion.insert((*meta, fusion));
        let stats = match fusion.fuse(points) {
            Ok(stats) => stats,
            Err(error) => {
                self.counters.clouds_rejected += 1;
                return Err(error);
            }
        };
        fusion.write_depth_mm(&mut self.depth_mm)?;
        self.valid = true;
        self.counters.clouds_fused += 1;
        Ok(stats)
    }

    /// The fused depth image for a frame with geometry `meta`, or `None` when no cloud has
    /// been fused for that geometry yet: counted as a ToF fallback frame, or, for a colour-only
    /// frame (nothing to fall back on), as a frame without depth.
    pub fn depth_for(&mut self, meta: &RgbdFrameMeta) -> Option<&[u16]> {
        match &self.fusion {
            Some((built_for, _)) if self.valid && built_for == meta => Some(&self.depth_mm),
            _ if meta.is_color_only() => {
                self.counters.frames_without_depth += 1;
                None
            }
            _ => {
                self.counters.tof_fallback_frames += 1;
                None
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::Calibration;
    use crate::camera_setup::CameraSetup;
    use crate::node::PerceptionNode;
    use crate::pipeline::PerceptionConfig;
    use crate::synthetic::{SyntheticApple, SyntheticScene};
    use harvest_ipc::payloads::{AppleDetections, DepthSourceCode, RgbdFrame};

    const APPLE_CENTRE_M: [f64; 3] = [0.06, 0.04, 1.2];
    const APPLE_RADIUS_M: f64 = 0.04;
    const WALL_DEPTH_M: f64 = 2.0;

    fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
        a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
    }

    /// A noise-free LiDAR cloud of the apple in front of a flat wall, ray-cast from the LiDAR's
    /// origin over a grid of directions, returned in the LiDAR frame.
    fn synthetic_cloud(camera_from_lidar: &RigidTransform) -> Vec<LidarPoint> {
        let origin = camera_from_lidar.translation_m;
        let lidar_from_camera = camera_from_lidar.inverse();
        let steps = 400;
        let mut cloud = Vec::with_capacity(steps * steps);
        for i in 0..steps {
            for j in 0..steps {
                let d = [
                    -0.6 + 1.2 * i as f64 / steps as f64,
                    -0.6 + 1.2 * j as f64 / steps as f64,
                    1.0,
                ];
                let oc = [
                    origin[0] - APPLE_CENTRE_M[0],
                    origin[1] - APPLE_CENTRE_M[1],
                    origin[2] - APPLE_CENTRE_M[2],
                ];
                let (a, b, c) = (
                    dot(d, d),
                    2.0 * dot(d, oc),
                    dot(oc, oc) - APPLE_RADIUS_M * APPLE_RADIUS_M,
                );
                let disc = b * b - 4.0 * a * c;
                let s = if disc >= 0.0 {
                    (-b - disc.sqrt()) / (2.0 * a)
                } else {
                    (WALL_DEPTH_M - origin[2]) / d[2]
                };
                let p = lidar_from_camera.apply([
                    origin[0] + s * d[0],
                    origin[1] + s * d[1],
                    origin[2] + s * d[2],
                ]);
                cloud.push(LidarPoint {
                    x_m: p[0] as f32,
                    y_m: p[1] as f32,
                    z_m: p[2] as f32,
                    intensity: 80.0,
                });
            }
        }
        cloud
    }

    /// The apple rendered in colour with the ToF depth image blanked: any position must come
    /// from the fused depth.
    fn frame_without_tof_depth(cameras: &CameraSetup) -> Box<RgbdFrame> {
        let scene = SyntheticScene {
            apples: vec![SyntheticApple {
                center_in_camera_m: APPLE_CENTRE_M,
                radius_m: APPLE_RADIUS_M,
                albedo: [0.75, 0.08, 0.09],
            }],
            leaves: Vec::new(),
            branches: Vec::new(),
            background_depth_m: WALL_DEPTH_M,
            sky_below_y_m: -100.0,
            light_gain: 1.0,
            depth_noise_scale: 1.0,
            depth_dropout_fraction: 0.0,
            flying_pixel_fraction: 0.0,
            seed: 1,
        };
        let rendered = scene.render(cameras);
        let mut frame: Box<RgbdFrame> = harvest_ipc::payload::boxed_zeroed();
        frame.meta.rgb_intrinsics = cameras.color;
        frame.meta.depth_intrinsics = cameras.depth;
        frame.meta.color_from_depth = cameras.color_from_depth;
        frame.rgb.copy_from_slice(&rendered.rgb);
        frame.depth_mm.fill(0);
        frame
    }

    #[test]
    fn fused_depth_localizes_a_known_apple_and_marks_it() {
        let calibration = Calibration::parse(
            include_str!("../../../sim/camera_calibration.toml"),
            "sim/camera_calibration.toml",
        )
        .expect("calibration");
        let cameras = CameraSetup::tl460_simulated(calibration.camera.robot_from_camera);
        let frame = frame_without_tof_depth(&cameras);
        let camera_from_lidar = harvest_lidar::CAD_CAMERA_FROM_LIDAR;
        let mut fused = FusedDepth::new(camera_from_lidar);
        let mut node = PerceptionNode::new(PerceptionConfig::default(), calibration);
        let mut out: Box<AppleDetections> = Box::default();

        // Before the first cloud: ToF fallback (here no depth at all, so no apple), counted.
        assert!(fused.depth_for(&frame.meta).is_none());
        node.process_with_depth(&frame, None, &mut out)
            .expect("process");
        assert!(out.apples.is_empty());
        assert_eq!(fused.counters().tof_fallback_frames, 1);

        let stats = fused
            .update(&frame.meta, &synthetic_cloud(&camera_from_lidar))
            .expect("fuse");
        assert!(stats.depth_pixels > 1000, "{stats:?}");
        // An empty cloud is refused and the previous fused depth stays in use.
        assert!(fused.update(&frame.meta, &[]).is_err());
        assert_eq!(fused.counters().clouds_fused, 1);
        assert_eq!(fused.counters().clouds_rejected, 1);

        let depth = fused.depth_for(&frame.meta).expect("fused depth");
        node.process_with_depth(&frame, Some(depth), &mut out)
            .expect("process");
        assert_eq!(out.apples.len(), 1, "{:?}", out.apples);
        let apple = *out.apples.iter().next().expect("one apple");
        assert_eq!(apple.depth_source, DepthSourceCode::LidarFused);
        let error_m = (0..3)
            .map(|k| (apple.position_in_camera_m[k] - APPLE_CENTRE_M[k]).powi(2))
            .sum::<f64>()
            .sqrt();
        assert!(error_m < 0.005, "error {error_m} m at {apple:?}");

        // A depth image of another size rejects the frame.
        assert!(
            node.process_with_depth(&frame, Some(&depth[..100]), &mut out)
                .is_err()
        );
        assert_eq!(fused.counters().tof_fallback_frames, 1);
    }

    #[test]
    fn a_colour_only_frame_is_refused_until_lidar_depth_is_fused_then_localized_from_it() {
        let calibration = Calibration::parse(
            include_str!("../../../sim/camera_calibration.toml"),
            "sim/camera_calibration.toml",
        )
        .expect("calibration");
        // A GigE camera's frame: the colour camera's view, its depth grid a pinhole through it.
        let color = harvest_ipc::camera_model::CameraIntrinsics::tl460_rgb();
        let cameras = CameraSetup {
            color,
            depth: harvest_hw::rgbd_camera::gige::fused_depth_grid(&color),
            color_from_depth: RigidTransform::IDENTITY,
            robot_from_camera: calibration.camera.robot_from_camera,
        };
        let mut frame = frame_without_tof_depth(&cameras);
        frame.header.msg_seq = 7;
        frame.meta.flags = RgbdFrameMeta::FLAG_COLOR_ONLY;
        let camera_from_lidar = harvest_lidar::CAD_CAMERA_FROM_LIDAR;
        let mut fused = FusedDepth::new(camera_from_lidar);
        let mut node = PerceptionNode::new(PerceptionConfig::default(), calibration);
        let mut out: Box<AppleDetections> = Box::default();

        assert!(fused.depth_for(&frame.meta).is_none());
        assert_eq!(fused.counters().frames_without_depth, 1);
        assert_eq!(fused.counters().tof_fallback_frames, 0);
        let refused = node
            .process_with_depth(&frame, None, &mut out)
            .expect_err("no depth source");
        assert_eq!(
            refused,
            crate::pipeline::PerceptionSetupError::NoDepthSource { frame_seq: 7 }
        );
        assert!(refused.to_string().contains("lidar-fused"), "{refused}");
        assert_eq!(node.frames_rejected(), 1);
        assert!(out.apples.is_empty());

        fused
            .update(&frame.meta, &synthetic_cloud(&camera_from_lidar))
            .expect("fuse");
        let depth = fused.depth_for(&frame.meta).expect("fused depth");
        node.process_with_depth(&frame, Some(depth), &mut out)
            .expect("process");
        assert_eq!(out.apples.len(), 1, "{:?}", out.apples);
        let apple = *out.apples.iter().next().expect("one apple");
        assert_eq!(apple.depth_source, DepthSourceCode::LidarFused);
        let error_m = (0..3)
            .map(|k| (apple.position_in_camera_m[k] - APPLE_CENTRE_M[k]).powi(2))
            .sum::<f64>()
            .sqrt();
        assert!(error_m < 0.01, "error {error_m} m at {apple:?}");
    }
}
