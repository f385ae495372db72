//! harvest-sim: the simulated orchard world of the dual-arm vacuum harvester.
//!
//! Pure, seeded logic without IPC: scenario files ([`scenario`]), generation of the canopy, apples
//! and occluders ([`orchard`]), rendering of the ToF camera's RGB and depth frames
//! ([`render_rgbd`]), the vacuum and contact physics plus joint servo dynamics ([`physics`]) and
//! the evaluation-only ground truth ([`ground_truth`]).
//!
//! The `harvest sim` process ([`process`]) serves the hardware channels from two threads: the
//! 200 Hz physics ([`physics_thread`]) and the renderers ([`render_thread`]), linked by a world
//! snapshot ([`thread_link`]).

#![forbid(unsafe_code)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]

pub mod alacs;
pub mod alacs_device;
pub mod fake_gige;
pub mod fake_mid70;
pub mod ground_truth;
pub mod lidar_device;
pub mod orchard;
pub mod physics;
pub mod physics_thread;
pub mod platform_device;
pub mod process;
pub mod render_rate;
pub mod render_rgbd;
pub mod render_thread;
pub mod robot;
#[cfg(test)]
mod robot_test_moves;
pub mod rosette_scan;
pub mod row;
pub mod row_world;
pub mod scenario;
pub mod thread_link;
pub mod tractor_device;
pub mod world_motion;
pub mod world_state;

pub use ground_truth::{AppleTruth, WorldTruth};
pub use orchard::{Apple, AppleId, AppleState, OrchardError, World};
pub use physics::{ArmId, DropCause, ReleaseOutcome, StepError, StepInputs, WorldEvent};
pub use render_rgbd::{RenderError, RgbdRenderer};
pub use scenario::{Scenario, ScenarioError};
