//! `harvest bench pipeline`: end-to-end latency inside a running stack on the simulated robot.
//!
//! The bench starts `harvest up` with its own launch file in a domain of its own (or attaches
//! to a running stack with `--attach`), subscribes to `camera/rgbd`, `perception/apples`,
//! `armN/target`, `armN/command` and `armN/state` through the stack's ipc layer, and follows
//! each frame down the pipeline by the header stamps ([`tracker`]): capture -> camera publish
//! -> perception result -> the vacuum process's arm target -> the arm's first command for it.
//! It also measures the arm control loop's period jitter at 200 Hz from consecutive publish
//! stamps ([`jitter`]). Hops whose channels carry nothing are reported as "no data".
//!
//! - [`run_bench_pipeline`] / [`BenchPipelineArgs`]: the benchmark, returning a
//!   [`PipelineReport`].

pub mod jitter;
pub mod options;
pub mod report;
pub mod run;
pub mod stack;
pub mod summary;
pub mod svg;
pub mod tracker;

pub use options::BenchPipelineArgs;
pub use report::PipelineReport;
pub use run::run_bench_pipeline;
