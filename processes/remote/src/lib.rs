//! The link between a robot and the operator's station over Zenoh.
//!
//! On the robot, `harvest remote` ([`bridge`]) publishes the channels of
//! `harvest_remote::channel_policy` under `harvest/v1/<robot>/...` at their rates and
//! priorities, the camera only while someone watches (`camera_thread.rs`), and answers operator
//! commands on two lanes (`command_lane.rs`) with the executive's own answer.
//!
//! On the station, `harvest ctl --remote ROBOT ...` ([`station_ctl`]) and `harvest fleet`
//! ([`fleet`]: every robot seen, one line each, in a browser).
//!
//! [`link_session`] opens the Zenoh session from the checked settings; the logic (keys, rates,
//! encodings, inbound checks, security rules) is in the transport-free `harvest-remote`.

#![forbid(unsafe_code)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]

pub mod bridge;
mod camera_thread;
mod command_lane;
pub mod error;
pub mod fleet;
pub mod link_session;
pub mod ros2_link;
pub mod station_ctl;

pub use bridge::{RemoteArgs, run};
pub use error::RemoteError;
/// The Zenoh crate the link is built on (for tools that measure it).
pub use zenoh;
