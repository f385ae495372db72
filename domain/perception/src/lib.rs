//! harvest-perception: apple detection in the RGB image and 3D localization from the registered
//! ToF depth image (Zhu et al., "Advancement and field evaluation of a dual-arm apple harvesting
//! robot", sections 2.1 and 3.1.3).
//!
//! Data flow for one frame ([`pipeline::Perception::process`]):
//! 1. [`detector`]: 2D apple detections (box, mask, visible pixel count, confidence) from the colour
//!    image; the default is the classical [`detector::color_segmentation::ColorSegmentation`].
//! 2. [`registration`]: every valid depth pixel is unprojected, moved into the colour camera frame
//!    and projected into the colour image, so each detection mask collects its 3D points.
//! 3. [`estimator`]: one 3D position per detection, either the paper's DBSCAN cluster-depth method
//!    or the bias-free robust sphere fit, selected by [`estimator::EstimatorKind`].
//! 4. Positions are reported in the colour camera frame and in the robot frame.
//! 5. [`laser_refiner`]: apples are followed over frames; hard ones (heavily occluded, uncertain
//!    depth: [`scan_policy`]) are sent to the ALACS laser scanner, and a scan's position replaces
//!    the ToF estimate in the apple's later detections.
//! 6. [`depth_source`]: the depth image may instead be the LiDAR cloud fused into the ToF depth
//!    image's geometry (config `depth_source = "lidar_fused"`).
//!
//! "Camera frame" in this crate always means the colour (RGB) camera frame: x right, y down,
//! z forward, metres.

#![forbid(unsafe_code)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]

pub mod apple_tracks;
pub mod blob_localization;
pub mod calibration;
pub mod camera_setup;
pub mod config_file;
pub mod dbscan;
pub mod depth_source;
pub mod detector;
pub mod downscale;
pub mod estimate_checks;
pub mod estimator;
pub mod frame;
pub mod frame_freshness;
pub mod laser_refiner;
pub mod node;
pub mod noise_model;
pub mod pipeline;
pub mod registration;
pub mod scan_policy;
pub mod stats;
pub mod synthetic;
pub mod task;
pub mod timing;

pub use camera_setup::CameraSetup;
pub use frame::{DepthView, FrameError, RgbView};
pub use pipeline::{AppleEstimate, Perception, PerceptionConfig};
pub use stats::{FrameStats, PerceptionStats};
