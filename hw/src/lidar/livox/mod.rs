//! The Livox Mid-70 over its own protocol (Livox SDK 1, MIT: `sdk_core/include/livox_def.h`,
//! `sdk_core/src/comm/sdk_protocol.*`, `comm_port.cpp`, `command_handler/*`,
//! `data_handler/*`), in pure Rust.
//!
//! - [`crc`]: CRC-16 and CRC-32 with the SDK's seeds.
//! - [`frame`]: the control frame (commands, acknowledgements, messages).
//! - [`command`]: ports, command ids and payloads of discovery, handshake, heartbeat, sampling.
//! - [`point_packet`]: point-data packets, data types 2 (extended Cartesian) and 4 (dual return).
//! - [`error_code`]: the device's status word.
//! - [`clock_mapping`]: device timestamps -> the stack's `CLOCK_MONOTONIC` (shared with the
//!   GigE camera: [`crate::clock_mapping`]).
//! - [`config`]: how to reach the device.
//! - [`session`]: the UDP session (discovery, handshake, heartbeat, sampling, silence).
//! - [`driver`]: [`LivoxLidar`], the [`crate::lidar::Lidar`] implementation.

pub use crate::clock_mapping;
pub mod command;
pub mod config;
pub mod crc;
pub mod driver;
pub mod error;
pub mod error_code;
pub mod frame;
pub mod point_packet;
pub mod session;

pub use config::{DeviceTarget, LivoxConfig};
pub use driver::{LivoxLidar, LivoxStats};
pub use error::LivoxError;
