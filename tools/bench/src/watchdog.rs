//! The peer process of one case, watched: it must stay alive and make progress, and it is
//! killed if the case ends early.

use crate::error::BenchError;
use std::process::Child;
use std::time::{Duration, Instant};

/// How often blocked receivers wake up to check the peer.
pub const WATCH_PERIOD: Duration = Duration::from_millis(100);

/// Owns the peer process of a case and bounds how long each phase may take.
pub struct Watchdog {
    child: Child,
    reaped: bool,
    case: String,
    phase: &'static str,
    phase_start: Instant,
    phase_limit: Duration,
    last_poll_check: Instant,
}

impl Watchdog {
    pub fn new(child: Child, case: String) -> Self {
        let now = Instant::now();
        Self {
            child,
            reaped: false,
            case,
            phase: "start",
            phase_start: now,
            phase_limit: Duration::from_secs(30),
            last_poll_check: now,
        }
    }

    pub fn case(&self) -> &str {
        &self.case
    }

    /// Starts a phase that must end within `limit`.
    pub fn start_phase(&mut self, phase: &'static str, limit: Duration) {
        self.phase = phase;
        self.phase_start = Instant::now();
        self.phase_limit = limit;
    }

    /// Fails if the peer exited or the phase ran out of time.
    pub fn check(&mut self) -> Result<(), BenchError> {
        if let Ok(Some(status)) = self.child.try_wait() {
            self.reaped = true;
            return Err(BenchError::PeerExited {
                case: self.case.clone(),
                status,
            });
        }
        let waited = self.phase_start.elapsed();
        if waited > self.phase_limit {
            return Err(BenchError::PeerTimeout {
                case: self.case.clone(),
                phase: self.phase,
                waited_s: waited.as_secs_f64(),
            });
        }
        Ok(())
    }

    /// [`Self::check`] at most once per [`WATCH_PERIOD`], for spinning loops.
    pub fn poll_check(&mut self) -> Result<(), BenchError> {
        if self.last_poll_check.elapsed() < WATCH_PERIOD {
            return Ok(());
        }
        self.last_poll_check = Instant::now();
        self.check()
    }

    /// Waits for the peer to exit successfully within `limit`.
    pub fn wait_exit(&mut self, limit: Duration) -> Result<(), BenchError> {
        let start = Instant::now();
        loop {
            match self.child.try_wait() {
                Ok(Some(status)) => {
                    self.reaped = true;
                    if status.success() {
                        return Ok(());
                    }
                    return Err(BenchError::PeerExited {
                        case: self.case.clone(),
                        status,
                    });
                }
                Ok(None) | Err(_) if start.elapsed() > limit => {
                    return Err(BenchError::PeerTimeout {
                        case: self.case.clone(),
                        phase: "exit",
                        waited_s: start.elapsed().as_secs_f64(),
                    });
                }
                Ok(None) | Err(_) => std::thread::sleep(Duration::from_millis(2)),
            }
        }
    }
}

impl Drop for Watchdog {
    fn drop(&mut self) {
        if !self.reaped {
            // The case failed: the peer must not outlive it (it holds iceoryx2 ports).
            if let Err(error) = self.child.kill() {
                tracing::debug!(case = self.case, %error, "peer already gone");
            }
            if let Err(error) = self.child.wait() {
                tracing::warn!(case = self.case, %error, "cannot reap the peer process");
            }
        }
    }
}
