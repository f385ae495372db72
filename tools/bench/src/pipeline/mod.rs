//! `harvest bench pipeline`: end-to-end latency inside a running stack on the simulated robot.
//!
//! The bench starts `harvest up` with its own launch file in a domain of its own (or attaches
//! to a running stack with `--attach`), subscribes to `camera/rgbd`, `perception/apples`,
//! `armN/target`, `armN/command` and `armN/state` through the stack's ipc layer, and follows
//! each frame down the pipeline by the header stamps ([`tracker`]): capture -> camera publish
//! -> perception result -> the vacuum process's arm target -> the arm's first command for it.
//! It also measures the period jitter of the 200 Hz loops (arms, vacuum supervisor) from
//! consecutive publish stamps ([`jitter`]), with the launch file's scheduling settings and
//! without them in one invocation, optionally beside `--load N` busy threads ([`comparison`],
//! [`cpu_load`]). Hops whose channels carry nothing are reported as "no data".
//!
//! - [`run_bench_pipeline`] / [`BenchPipelineArgs`]: the benchmark, returning a
//!   [`PipelineReport`].

pub mod comparison;
pub mod cpu_load;
pub mod jitter;
pub mod options;
pub mod report;
pub mod run;
pub mod stack;
pub mod summary;
pub mod svg;
pub mod tracker;

pub use comparison::PipelineComparison;
pub use options::BenchPipelineArgs;
pub use report::PipelineReport;
pub use run::run_bench_pipeline;
