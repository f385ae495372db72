//! The process supervisor behind `harvest up`.

pub mod child;
pub mod launch;
pub mod restart_tracker;
pub mod status;
pub mod supervisor;

pub use launch::{Launch, LaunchError};
pub use supervisor::{Summary, SupervisorError, UpOptions, run};

/// The processes `harvest up` launches whose crates the root package reaches through this one:
/// `harvest arm` and `harvest vacuum` (the root `Cargo.toml` does not list `harvest-arm` and
/// `harvest-vacuum`; once it does, the CLI can name them directly and this can go).
pub mod stack_processes {
    pub use harvest_arm::process as arm;
    pub use harvest_vacuum::process as vacuum;
}
