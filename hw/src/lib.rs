//! Hardware layer: one trait per device class, the shared error kinds, and the implementations
//! (simulated devices reached over iceoryx2 hardware channels, and real drivers).

#![forbid(unsafe_code)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]
#![deny(missing_docs)]

pub mod alacs;
pub mod arm_servos;
pub mod clock_mapping;
#[cfg(any(test, feature = "testing"))]
pub mod conformance;
pub mod error_kind;
pub mod lidar;
pub mod platform;
pub mod rgbd_camera;
pub mod tractor;
pub mod valve_board;

pub use error_kind::{AnyDeviceError, DeviceError, ErrorKind};
