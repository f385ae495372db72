//! A process a benchmark runs (a device driver against its fake device: `harvest lidar`,
//! `harvest camera`; the remote link's robot and station sides): interrupted (then killed) when
//! dropped.

use std::process::Child;
use std::time::{Duration, Instant};

/// A benchmark's child process; SIGINT when dropped, SIGKILL if it has not exited 5 s later.
pub struct DriverChild(pub Child);

impl Drop for DriverChild {
    fn drop(&mut self) {
        let pid = nix::unistd::Pid::from_raw(self.0.id() as i32);
        let _ = nix::sys::signal::kill(pid, nix::sys::signal::Signal::SIGINT);
        let deadline = Instant::now() + Duration::from_secs(5);
        while Instant::now() < deadline {
            if matches!(self.0.try_wait(), Ok(Some(_))) {
                return;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}
