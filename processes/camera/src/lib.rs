//! The camera process: acquires RGB-D frames from the camera device and publishes them on
//! `camera/rgbd`, written in place into loaned shared memory.

pub mod process;

pub use process::{CameraArgs, CameraError, run};
