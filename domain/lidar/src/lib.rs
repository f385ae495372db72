//! harvest-lidar: the solid-state LiDAR path of the perception stack ([fusion sec. II]:
//! Kang, Wang and Chen, "Accurate fruit localisation using high resolution LiDAR-camera fusion").
//!
//! - [`fusion`]: [fusion eq. 1-2], LiDAR points into the colour image: registered depth image,
//!   colourised cloud, mask points.
//! - [`capture`]: a LiDAR driver as the device of the `harvest lidar` source node, with its
//!   heartbeat.
//! - [`extrinsic_file`]: the calibrated `camera_from_lidar` as `harvest calibrate lidar-camera`
//!   writes it (the calibration itself is in `harvest-calibrate`).
//! - [`integration_window`]: how long returns are integrated into one cloud.
//! - [`localization`]: fused fruit localization ([fusion sec. II-D-3], Z-score rejection,
//!   [fusion eq. 20]).
//!
//! The `harvest lidar` process is `harvest-lidar-process`; `harvest eval lidar` is in
//! `harvest-eval`.

#![forbid(unsafe_code)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]

pub mod capture;
pub mod extrinsic_file;
pub mod fusion;
pub mod integration_window;
pub mod localization;

pub use extrinsic_file::{ExtrinsicFile, ReadExtrinsicError};
pub use fusion::{Fusion, FusionConfig, FusionError, FusionStats};
/// The designed (CAD) `camera_from_lidar` extrinsic, the calibration's starting point.
pub use harvest_hw::lidar::mounting::CAD_CAMERA_FROM_LIDAR;
pub use localization::{FruitPosition, ZScoreConfig, localize_fruit};
