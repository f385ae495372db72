//! Fault-injection fixtures: tiny processes named for their behaviour, for supervisor tests.

use anyhow::{Context as _, Result};
use harvest_ipc::payloads::ProcessRunState;
use harvest_ipc::{Context, Domain, Flow, HEARTBEAT_PERIOD, HealthReporter, Waiter};

#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Behaviour {
    /// Exits with status 3 right away.
    AlwaysCrash,
    /// Sends heartbeats for one second, then stops sending them but keeps running.
    HangAfterInit,
    /// Ignores SIGTERM (only SIGKILL ends it).
    IgnoreSigterm,
}

pub fn run(behaviour: Behaviour, domain: &Domain, process_name: &str) -> Result<()> {
    match behaviour {
        Behaviour::AlwaysCrash => {
            tracing::error!("fixture: crashing at start");
            std::process::exit(3);
        }
        Behaviour::HangAfterInit => {
            let context = Context::new(domain, process_name)?;
            let mut health = HealthReporter::new(&context)?;
            for _ in 0..2 {
                health.report(ProcessRunState::Running, 0, "", 0)?;
                std::thread::sleep(HEARTBEAT_PERIOD);
            }
            tracing::warn!("fixture: hanging now");
            loop {
                std::thread::park();
            }
        }
        Behaviour::IgnoreSigterm => {
            // SAFETY: setting a signal to SIG_IGN has no handler code to be unsafe about.
            unsafe {
                nix::sys::signal::signal(
                    nix::sys::signal::Signal::SIGTERM,
                    nix::sys::signal::SigHandler::SigIgn,
                )
            }
            .context("ignoring SIGTERM")?;
            let context = Context::new(domain, process_name)?;
            let mut health = HealthReporter::new(&context)?;
            let waiter = Waiter::new()?;
            let _tick = waiter.attach_interval(HEARTBEAT_PERIOD)?;
            let _ = waiter.run(|_| -> Result<Flow> {
                health.report(ProcessRunState::Running, 0, "", 0)?;
                Ok(Flow::Continue)
            });
            loop {
                std::thread::park();
            }
        }
    }
}
