//! `harvest calibrate lidar-camera`: the target-based LiDAR-camera extrinsic calibration of
//! [fusion sec. II-C-1, eq. 3-5] with its Table-I-style report.
//!
//! - [`checkerboard`], [`board_image`], [`image_corners`]: the board, its rendered views and the
//!   corners found in them; [`cloud_corners`]: the board's corners fitted in the cloud;
//!   [`extrinsic_solver`]: Levenberg-Marquardt on the reprojection error (eq. 3).
//! - [`calibration_scenes`]: generated views of the simulated orchard with the board.
//! - [`calibration_data`]: the data-set directory (camera.toml, NN.png + NN.csv per view) that
//!   recorded captures are calibrated from (`--data`) and generated scenes are written to
//!   (`--write-generated`).
//! - [`calibration`]: the command and the report.

pub mod board_image;
pub mod calibration;
pub mod calibration_data;
pub mod calibration_scenes;
pub mod checkerboard;
pub mod cloud_corners;
pub mod extrinsic_solver;
pub mod image_corners;

pub use calibration::{
    CalibrateLidarCameraArgs, CalibrationError, CalibrationReport, calibrate,
    run_calibrate_lidar_camera,
};
