//! The operator's station beside the robot: `harvest console --remote ROBOT` serves the same
//! page as the robot's console, fed over the remote link instead of the robot's shared memory
//! ([`remote_console`]). What the robot's `harvest remote` sends (mode, arm and vacuum states,
//! detections, events, heartbeats, the camera as JPEG while a page watches) feeds the same
//! status board ([`link_feed`]); the page's commands go to the robot's command and e-stop keys
//! and come back with the executive's own answer ([`link_port`]). The e-stop needs no token;
//! every other command carries the one the operator typed, as on the robot.

#![forbid(unsafe_code)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]

pub mod error;
pub mod link_feed;
pub mod link_port;
pub mod relayed_sessions;
pub mod remote_console;

pub use error::StationError;
pub use remote_console::run;
