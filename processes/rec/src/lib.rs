//! harvest-rec: the recording tools: `harvest rec info|cat|export|recover` ([`rec`]) and
//! `harvest replay` ([`replay`]), which republishes a recording into a domain's channels at
//! recorded timing (space pauses, arrows step: [`keyboard`]), also from ROS 2 bags
//! ([`ros2_input`]); the continuous record's camera video is decoded back into frames
//! ([`video_replay`]). `harvest replay --check` ([`check`]) re-runs this build's perception on a
//! recording and compares what it decides with what was recorded.

#![forbid(unsafe_code)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]

pub mod check;
pub mod keyboard;
pub mod rec;
pub mod replay;
pub mod ros2_input;
pub mod video_replay;

pub use check::{CheckError, CheckReport, run_check};
pub use rec::{RecCommand, RecError, run_rec};
pub use replay::{ReplayArgs, ReplayError, ReplayReport, run_replay};
