//! harvest-remote: the pure logic of the link between a robot and the operator's station over
//! Zenoh, with no Zenoh and no iceoryx2 in it (the `harvest remote` process and the station
//! wire them).
//!
//! - [`robot_name`], [`keys`]: every key lives under `harvest/v1/<robot>/...`; the one place
//!   that spells them and reads a robot's name back from a key.
//! - [`channel_policy`]: which stack channels leave the robot, at what rate, with what priority
//!   (the e-stop express and highest); raw frames and arm commands are not in the table, so
//!   they never leave.
//! - [`rate_gate`]: latest-only rate limits and "on change plus a slow beat".
//! - [`state_encoding`] and [`state_decoding`], [`camera_image`], [`fleet_summary`]: the payloads the station reads
//!   (JSON for states, a downscaled JPEG for the camera, one summary per robot for the fleet).
//! - [`remote_request`], [`inbound_gate`], [`token_bucket`]: an operator command from the
//!   station: size, syntax and rate checked before the executive sees it, every refusal counted.
//! - [`link_settings`]: the link's TOML settings, the security rules (loopback only unless
//!   configured; beyond loopback TLS plus user/password or certificates; viewers cannot command)
//!   and the Zenoh configuration they become.
//! - [`ros2_graph`]: the robot as a ROS 2 node over rmw_zenoh (topic keys, liveliness tokens,
//!   the sample attachment).

#![forbid(unsafe_code)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]

pub mod camera_image;
pub mod channel_policy;
pub mod fleet_summary;
pub mod inbound_gate;
pub mod keys;
pub mod link_settings;
pub mod rate_gate;
pub mod remote_request;
pub mod robot_name;
pub mod ros2_graph;
pub mod state_decoding;
pub mod state_encoding;
pub mod token_bucket;

pub use channel_policy::{ChannelPolicy, LinkPriority, Outbound, Pace};
pub use inbound_gate::{InboundCounters, InboundGate, InboundRefusal};
pub use keys::RobotKeys;
pub use link_settings::{LinkSettings, SettingsError};
pub use rate_gate::{ChangeBeat, RateGate};
pub use remote_request::{RemoteReply, RemoteRequest};
pub use robot_name::RobotName;
