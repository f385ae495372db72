//! `harvest up`: the whole stack under the process supervisor.

use anyhow::{Context as _, Result};
use clap::Args;
use harvest_ipc::Domain;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

/// What `harvest up` runs and when it stops by itself.
#[derive(Debug, Args)]
pub struct UpArgs {
    /// Launch file (TOML); the embedded default runs the whole stack in simulation.
    #[arg(long)]
    launch: Option<PathBuf>,
    /// Stop by itself after this long (e.g. 10s, 2m).
    #[arg(long, value_parser = harvest_ipc::duration::parse_duration)]
    duration: Option<Duration>,
    /// Stop once the vacuum supervisor reports that nothing is left to pick.
    #[arg(long)]
    until_harvested: bool,
    /// Ignore the launch file's `[process.scheduling]` settings (real-time priority, CPU
    /// affinity, nice, memory lock): every process runs with normal scheduling.
    #[arg(long)]
    no_scheduling: bool,
    /// Stop once the executive's stop-and-go cycle finished the row's last stop (a launch
    /// with a row, e.g. processes/supervisor/launch/row.toml).
    #[arg(long)]
    until_row_done: bool,
}

/// Runs the stack of `args` in `domain` and prints its summaries; fails when a process failed
/// for good.
pub fn up(args: UpArgs, domain: Domain) -> Result<ExitCode> {
    let UpArgs {
        launch,
        duration,
        until_harvested,
        no_scheduling,
        until_row_done,
    } = args;
    let launch = match &launch {
        Some(path) => harvest_supervisor::Launch::from_path(path)?,
        None => harvest_supervisor::Launch::default_stack()?,
    };
    let launch = if no_scheduling {
        launch.without_scheduling()
    } else {
        launch
    };
    let executable = std::env::current_exe().context("locating the harvest executable")?;
    let summary = harvest_supervisor::run(harvest_supervisor::UpOptions {
        launch,
        domain,
        duration,
        executable,
        until_harvested,
        until_row_done,
    })?;
    if let Some(harvest) = summary.render_harvest() {
        print!("{harvest}");
    }
    print!("{}", summary.render_safety());
    eprint!("{}", summary.render());
    Ok(if summary.failure.is_some() {
        ExitCode::FAILURE
    } else {
        ExitCode::SUCCESS
    })
}
