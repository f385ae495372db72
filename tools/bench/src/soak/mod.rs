//! `harvest soak`: the whole stack for a long time under faults, and what it left behind.
//!
//! The soak starts `harvest up` with the default launch file (a copy with the console and the
//! Foxglove bridge on free ports, [`stack`]) in a domain of its own and, on a schedule made from
//! `--seed` ([`schedule`]): SIGKILLs random stack processes (the supervisor restarts them), runs
//! operator scenarios through `harvest ctl` (pause/resume, stop/home/start, estop/release/start,
//! arm disable/enable, status) and feeds bad inputs (a wrong token, a jog past the limits, random
//! bytes on `operator/command`, `harvest/events` and `system/health`, a spoofed heartbeat;
//! [`inputs`]). Once the vacuum supervisor reports nothing left to pick it replants: the
//! simulator and the vacuum supervisor are killed and the world state file removed, so the
//! simulator restarts with the scenario's apples and the robot harvests again. Meanwhile it
//! samples every process's RSS, descriptors and threads from `/proc` ([`procs`]) and the
//! domain's shared-memory files, and follows `system/health` (recorder drops),
//! `sim/ground_truth`, `harvest/events` and `safety/violation`. The [`report`] gives restarts
//! (explained by its own kills or not), figures per process at start, middle and end, growth
//! slopes over the second half against stated bounds, and the verdicts.

pub mod error;
pub mod inputs;
pub mod options;
pub mod procs;
pub mod report;
pub mod run;
pub mod schedule;
pub mod stack;

pub use error::SoakError;
pub use options::SoakArgs;
pub use report::SoakReport;
pub use run::run_soak;
