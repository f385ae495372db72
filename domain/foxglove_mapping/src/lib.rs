//! harvest-foxglove-mapping: the one mapping from the stack's channels to Foxglove's
//! well-known schemas (protobuf), shared by the live bridge (`harvest foxglove`), the
//! recorder's mapped channels and `harvest rec export --foxglove`.
//!
//! | stack channel | mapped topics ([`topics`]) |
//! |---|---|
//! | `camera/rgbd` | `/camera/image` (JPEG), `/camera/calibration`, camera mounting on `/tf` ([`camera`]) |
//! | `perception/apples` | `/camera/annotations`, `/apples/detected` ([`detections`]) |
//! | `armN/state` | `/tf` down the chain (eq. 1), `/armN/joints` ([`arm_frames`]), `/robot_model` ([`robot_scene`]) |
//! | `vacuum/state` | `/vacuum` ([`vacuum`], our protobuf schema `harvest.VacuumView`) |
//! | `harvest/events`, `safety/emergency_stop` | `/events` ([`events`]), `/apples/harvest` ([`harvest_apples`]) |
//! | `lidar/points`, `laser/scan_result` | `/lidar/cloud`, `/laser/scan` ([`point_clouds`]) |
//!
//! Frames: [`frames`]. Time: [`stamps`]. Viewing rates: [`rates`]. Pure: no transport, no
//! network, no files; a [`topics::MappedSink`] takes the messages.

#![forbid(unsafe_code)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]

pub mod arm_frames;
pub mod camera;
pub mod color;
pub mod detections;
pub mod encoded;
pub mod error;
pub mod events;
pub mod frames;
pub mod geometry;
pub mod harvest_apples;
pub mod mounting_files;
pub mod point_clouds;
pub mod rates;
pub mod robot_scene;
pub mod stack_mapper;
pub mod stamps;
pub mod topics;
pub mod vacuum;

pub use camera::{CameraMapper, ImageSettings, JpegEncoder};
pub use encoded::EncodedMapper;
pub use error::MapError;
pub use rates::{RateLimit, ViewingRates};
pub use stack_mapper::{Mounting, StackMapper};
pub use stamps::TimeBase;
pub use topics::{MappedSink, Topic, TopicDescription};
