//! harvest-lidar: the solid-state LiDAR path of the perception stack (Kang, Wang and Chen,
//! "Accurate fruit localisation using high resolution LiDAR-camera fusion").
//!
//! - [`fusion`]: eq. 1-2, LiDAR points into the colour image: registered depth image,
//!   colourised cloud, mask points.
//! - [`checkerboard`], [`board_image`], [`image_corners`], [`calibration_scenes`],
//!   [`cloud_corners`], [`extrinsic_solver`], [`calibration`]: the target-based extrinsic
//!   calibration (section II-C-1, eq. 3-5) behind `harvest calibrate lidar-camera`, with its
//!   Table-I-style report; the board is rendered per view and its corners found in the image.
//!   [`calibration_data`]: the data-set directory (camera.toml, NN.png + NN.csv per view) that
//!   recorded captures are calibrated from (`--data`) and generated scenes are written to
//!   (`--write-generated`).
//! - [`localization`]: fused fruit localization (section II-D-3, Z-score rejection, eq. 20).
//! - [`evaluation`]: `harvest eval lidar`, the Table-III-style repeatability of fused versus ToF
//!   localization in the simulated orchard, and the fusion time.
//! - [`process`]: `harvest lidar`, LiDAR device -> `lidar/points`.

pub mod board_image;
pub mod calibration;
pub mod calibration_data;
pub mod calibration_scenes;
pub mod checkerboard;
pub mod cloud_corners;
pub mod evaluation;
pub mod extrinsic_solver;
pub mod fusion;
pub mod image_corners;
pub mod integration_window;
pub mod localization;
pub mod process;

pub use calibration::{
    CalibrateLidarCameraArgs, CalibrationError, CalibrationReport, ExtrinsicFile,
    ReadExtrinsicError, calibrate, run_calibrate_lidar_camera,
};
pub use evaluation::{EvalLidarArgs, run_eval_lidar};
pub use fusion::{Fusion, FusionConfig, FusionError, FusionStats};
/// The designed (CAD) and the simulated unit's `camera_from_lidar` extrinsics.
pub use harvest_hw::lidar::mounting::{CAD_CAMERA_FROM_LIDAR, simulated_camera_from_lidar};
pub use localization::{FruitPosition, ZScoreConfig, localize_fruit};
pub use process::{LidarArgs, LidarProcessError};
