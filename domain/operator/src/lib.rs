//! harvest-operator: what the operator may ask of the stack, and the one place that decides
//! ([dual-arm sec. 3.4]: the GUI's control panel).
//!
//! - [`command`]: the typed operator commands, decoded from `operator/command` (an unknown
//!   code is refused, never acted on) and encoded by the clients (`harvest ctl`, the console).
//! - [`executive`]: the mode machine (idle, harvesting, paused, manual, e-stopped), the token
//!   check, the single controlling session and the manual-mode heartbeat; it turns each
//!   command into an acknowledgement and [`action::Action`]s the `harvest executive` process
//!   carries out.
//! - [`motion_check`]: jogs, drop-off and home moves checked against the Table 1 joint limits
//!   and the clearance between the arms before anything moves.
//! - [`token`]: the control token `harvest up` makes, its file and its check.
//! - [`request`]: the console's JSON command requests.
//!
//! Transport-free: the process feeds commands and the arms' states in and publishes what comes
//! out.

#![forbid(unsafe_code)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]

pub mod action;
pub mod command;
pub mod executive;
pub mod mode_file;
pub mod motion_check;
pub mod refusal;
pub mod request;
pub mod stack_view;
pub mod token;

pub use action::Action;
pub use command::{Command, JointName};
pub use executive::{Decision, Executive, ExecutiveConfig};
pub use refusal::Refusal;
pub use stack_view::{ArmView, PlatformView, StackView};
pub use token::ControlToken;
