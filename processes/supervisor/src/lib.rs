//! The process supervisor behind `harvest up`.

#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]

pub mod child;
pub mod domain_lock;
pub mod launch;
pub mod restart_tracker;
pub mod scheduling;
pub mod status;
pub mod supervisor;
pub mod violation_log;

pub use domain_lock::{DomainLock, DomainLockError};
pub use launch::{Launch, LaunchError};
pub use supervisor::{Summary, SupervisorError, UpOptions, run};
pub use violation_log::{ViolationLog, violation_line};
