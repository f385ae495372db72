//! The camera process: acquires RGB-D frames from the camera device and publishes them on
//! `camera/rgbd`, written in place into loaned shared memory.

#![forbid(unsafe_code)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]

pub mod process;

pub use process::{CameraArgs, CameraError, run};
