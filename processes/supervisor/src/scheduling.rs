//! How a process of the launch file is scheduled: real-time priority (`SCHED_FIFO`), CPU
//! affinity, nice level and memory locking (`[process.scheduling]`, see [`crate::launch`]).
//!
//! Applied to the child between `fork` and `exec` ([`PreparedScheduling::apply_in_child`], only
//! async-signal-safe system calls: `setpriority`, `sched_setaffinity`, `sched_setscheduler`, and a
//! `write` of the outcome), so the process and every thread it starts run with them from their
//! first instruction. A refusal does not stop the start: the child writes what each call
//! returned to a pipe the supervisor reads right after the spawn ([`SchedulingOutcome`]), and the
//! supervisor warns and shows it in its status. Why not from the parent after the spawn
//! (`sched_setscheduler(pid)`): that applies to the main thread only, after the child already
//! started running (threads it started keep the old policy), and races the start of its loop.
//!
//! The memory lock is the exception: `mlockall` does not survive `exec`, so the supervisor sets
//! [`harvest_ipc::memory_lock::LOCK_MEMORY_ENV`] and the process locks itself before its loop's
//! first tick, once what the loop touches exists ([`harvest_ipc::memory_lock`]). The supervisor
//! reads the result from the kernel (`VmLck` in `/proc/<pid>/status`).

use std::fmt;
use std::io::Read as _;
use std::os::fd::{AsRawFd as _, OwnedFd, RawFd};

use nix::errno::Errno;
use nix::libc;

/// Highest `SCHED_FIFO` level.
pub const MAX_REALTIME_PRIORITY: u8 = 99;
/// Nice levels a launch file may ask for.
pub const NICE_RANGE: std::ops::RangeInclusive<i8> = -20..=19;

/// A process's scheduling settings, validated (none set: the process runs like any other).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Scheduling {
    /// `SCHED_FIFO` level, 1-99 (higher preempts lower; every `SCHED_FIFO` task preempts every
    /// normal one).
    pub realtime_priority: Option<u8>,
    /// CPUs the process may run on (empty: any).
    pub cpus: Vec<usize>,
    /// Nice level, -20..19 (matters for normal scheduling: without a real-time priority, or
    /// when it is refused).
    pub nice: Option<i8>,
    /// Lock all of the process's memory before its loop starts.
    pub lock_memory: bool,
}

impl Scheduling {
    /// True when nothing is asked.
    pub fn is_default(&self) -> bool {
        *self == Self::default()
    }

    /// What the child applies before `exec`.
    pub fn prepare(&self) -> PreparedScheduling {
        let cpu_set = (!self.cpus.is_empty()).then(|| {
            // SAFETY: cpu_set_t is a plain bit array; all-zero is the empty set.
            let mut set: libc::cpu_set_t = unsafe { std::mem::zeroed() };
            for &cpu in &self.cpus {
                // SAFETY: CPU_SET only writes bit `cpu` of the set; launch validation keeps
                // `cpu` below CPU_SETSIZE (the machine's CPUs).
                unsafe { libc::CPU_SET(cpu, &mut set) };
            }
            set
        });
        PreparedScheduling {
            realtime_priority: self.realtime_priority.map(libc::c_int::from),
            cpu_set,
            nice: self.nice.map(libc::c_int::from),
        }
    }
}

impl fmt::Display for Scheduling {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut parts = Vec::new();
        if let Some(priority) = self.realtime_priority {
            parts.push(format!("SCHED_FIFO {priority}"));
        }
        if !self.cpus.is_empty() {
            parts.push(format!("CPUs {}", cpu_list(&self.cpus)));
        }
        if let Some(nice) = self.nice {
            parts.push(format!("nice {nice}"));
        }
        if self.lock_memory {
            parts.push("memory locked".to_owned());
        }
        if parts.is_empty() {
            f.write_str("default scheduling")
        } else {
            f.write_str(&parts.join(", "))
        }
    }
}

/// `[0, 1, 3]` as `0,1,3`.
pub fn cpu_list(cpus: &[usize]) -> String {
    cpus.iter()
        .map(ToString::to_string)
        .collect::<Vec<_>>()
        .join(",")
}

/// The CPUs of this machine that are online (`/sys/devices/system/cpu/online`, e.g. `0-3,6`;
/// if unreadable, `0..available_parallelism`). Checked against the whole machine, not this
/// process's affinity: a CPU isolated from the scheduler (`isolcpus=`) is not in the
/// supervisor's own mask but is exactly where a real-time loop may be pinned.
pub fn online_cpus() -> Vec<usize> {
    std::fs::read_to_string("/sys/devices/system/cpu/online")
        .ok()
        .and_then(|text| parse_cpu_ranges(text.trim()))
        .unwrap_or_else(|| {
            let count = std::thread::available_parallelism().map_or(1, usize::from);
            (0..count).collect()
        })
}

/// Parses a kernel CPU list (`0-3,6`).
fn parse_cpu_ranges(text: &str) -> Option<Vec<usize>> {
    let mut cpus = Vec::new();
    for part in text.split(',') {
        match part.split_once('-') {
            Some((first, last)) => {
                let (first, last): (usize, usize) = (first.parse().ok()?, last.parse().ok()?);
                cpus.extend(first..=last);
            }
            None => cpus.push(part.parse().ok()?),
        }
    }
    Some(cpus)
}

/// The scheduling calls' arguments, built before `fork` so the child only makes system calls.
#[derive(Clone, Copy)]
pub struct PreparedScheduling {
    realtime_priority: Option<libc::c_int>,
    cpu_set: Option<libc::cpu_set_t>,
    nice: Option<libc::c_int>,
}

/// Per call, what the child wrote: not asked, applied, or the errno.
const NOT_ASKED: i32 = -1;
const APPLIED: i32 = 0;
/// Bytes of the outcome record: nice, affinity, real-time priority (i32 each).
const OUTCOME_BYTES: usize = 12;

impl PreparedScheduling {
    /// Applies the settings to the calling process and writes the outcome record to
    /// `outcome_fd`. Never fails: a refused call is recorded, not returned.
    ///
    /// Async-signal-safe (it runs between `fork` and `exec`): `setpriority`,
    /// `sched_setaffinity`, `sched_setscheduler`, reading `errno` and `write`; no allocation.
    pub fn apply_in_child(&self, outcome_fd: RawFd) {
        let last_errno = || std::io::Error::last_os_error().raw_os_error().unwrap_or(-2);
        let mut outcome = [NOT_ASKED; 3];
        if let Some(nice) = self.nice {
            // SAFETY: plain system call on this process (who = 0).
            let result = unsafe { libc::setpriority(libc::PRIO_PROCESS, 0, nice) };
            outcome[0] = if result == 0 { APPLIED } else { last_errno() };
        }
        if let Some(set) = &self.cpu_set {
            // SAFETY: `set` is a valid cpu_set_t of the size passed.
            let result =
                unsafe { libc::sched_setaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), set) };
            outcome[1] = if result == 0 { APPLIED } else { last_errno() };
        }
        if let Some(priority) = self.realtime_priority {
            let param = libc::sched_param {
                sched_priority: priority,
            };
            // SAFETY: `param` is a valid sched_param for the duration of the call.
            let result = unsafe { libc::sched_setscheduler(0, libc::SCHED_FIFO, &param) };
            outcome[2] = if result == 0 { APPLIED } else { last_errno() };
        }
        let mut bytes = [0u8; OUTCOME_BYTES];
        for (chunk, value) in bytes.chunks_exact_mut(4).zip(outcome) {
            chunk.copy_from_slice(&value.to_ne_bytes());
        }
        // SAFETY: writes OUTCOME_BYTES from a live buffer to a descriptor this child owns; a
        // failed write leaves the parent with "outcome unknown", nothing worse.
        unsafe { libc::write(outcome_fd, bytes.as_ptr().cast(), OUTCOME_BYTES) };
    }
}

/// The pipe the child reports on: both ends close on `exec`, so once the spawn returned the
/// record is complete.
pub struct OutcomePipe {
    read: OwnedFd,
    write: OwnedFd,
}

impl OutcomePipe {
    pub fn new() -> std::io::Result<Self> {
        let (read, write) = nix::unistd::pipe2(nix::fcntl::OFlag::O_CLOEXEC)?;
        Ok(Self { read, write })
    }

    /// The end the child writes to.
    pub fn write_fd(&self) -> RawFd {
        self.write.as_raw_fd()
    }

    /// After the spawn returned: closes this process's write end and reads the child's record.
    pub fn read_outcome(self, asked: &Scheduling) -> SchedulingOutcome {
        drop(self.write);
        let mut bytes = [0u8; OUTCOME_BYTES];
        let mut file = std::fs::File::from(self.read);
        let record = match file.read_exact(&mut bytes) {
            Ok(()) => Some(bytes),
            Err(error) => {
                tracing::warn!(%error, "no scheduling report from the child");
                None
            }
        };
        let field = |index: usize| -> CallOutcome {
            let Some(bytes) = record else {
                return CallOutcome::Unknown;
            };
            let mut value = [0u8; 4];
            value.copy_from_slice(&bytes[index * 4..index * 4 + 4]);
            match i32::from_ne_bytes(value) {
                NOT_ASKED => CallOutcome::NotAsked,
                APPLIED => CallOutcome::Applied,
                errno => CallOutcome::Refused(Errno::from_raw(errno)),
            }
        };
        SchedulingOutcome {
            asked: asked.clone(),
            nice: field(0),
            affinity: field(1),
            realtime: field(2),
        }
    }
}

/// What became of one setting.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CallOutcome {
    NotAsked,
    Applied,
    /// The kernel refused (`EPERM`: no permission; `EINVAL`: e.g. a CPU outside the cpuset).
    Refused(Errno),
    /// The child's record could not be read.
    Unknown,
}

/// What the child was asked and what the kernel granted.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SchedulingOutcome {
    pub asked: Scheduling,
    pub nice: CallOutcome,
    pub affinity: CallOutcome,
    pub realtime: CallOutcome,
}

impl SchedulingOutcome {
    /// Nothing was asked.
    pub fn none() -> Self {
        Self {
            asked: Scheduling::default(),
            nice: CallOutcome::NotAsked,
            affinity: CallOutcome::NotAsked,
            realtime: CallOutcome::NotAsked,
        }
    }

    /// One warning per refused setting, saying what it means and what would allow it.
    pub fn refusals(&self) -> Vec<String> {
        let mut out = Vec::new();
        if let (CallOutcome::Refused(errno), Some(priority)) =
            (self.realtime, self.asked.realtime_priority)
        {
            out.push(format!(
                "real-time priority SCHED_FIFO {priority} refused ({errno}): the process runs \
                 with normal scheduling{}; allow it with CAP_SYS_NICE or LimitRTPRIO={priority} \
                 (and check kernel.sched_rt_runtime_us / the cgroup's cpu.rt_runtime_us)",
                self.asked
                    .nice
                    .map_or(String::new(), |nice| format!(" at nice {nice}"))
            ));
        }
        if let CallOutcome::Refused(errno) = self.affinity {
            out.push(format!(
                "CPU affinity {} refused ({errno}): the process runs on any CPU (are the CPUs \
                 in this cgroup's cpuset?)",
                cpu_list(&self.asked.cpus)
            ));
        }
        if let (CallOutcome::Refused(errno), Some(nice)) = (self.nice, self.asked.nice) {
            out.push(format!(
                "nice {nice} refused ({errno}): the process runs at nice 0; a negative nice \
                 needs CAP_SYS_NICE or LimitNICE"
            ));
        }
        out
    }

    /// Short form for the status line: `fifo80 cpu1 nice-5 mlock`, refused parts as
    /// `fifo80:EPERM`; empty when nothing was asked.
    pub fn label(&self) -> String {
        let mark = |outcome: CallOutcome| match outcome {
            CallOutcome::Refused(errno) => format!(":{}", errno.desc_short()),
            CallOutcome::Unknown => ":?".to_owned(),
            _ => String::new(),
        };
        let mut parts = Vec::new();
        if let Some(priority) = self.asked.realtime_priority {
            parts.push(format!("fifo{priority}{}", mark(self.realtime)));
        }
        if !self.asked.cpus.is_empty() {
            parts.push(format!(
                "cpu{}{}",
                cpu_list(&self.asked.cpus),
                mark(self.affinity)
            ));
        }
        if let Some(nice) = self.asked.nice {
            parts.push(format!("nice{nice}{}", mark(self.nice)));
        }
        if self.asked.lock_memory {
            parts.push("mlock".to_owned());
        }
        parts.join(" ")
    }
}

/// Short errno names for the status line.
trait ShortErrno {
    fn desc_short(self) -> &'static str;
}

impl ShortErrno for Errno {
    fn desc_short(self) -> &'static str {
        match self {
            Errno::EPERM => "EPERM",
            Errno::EINVAL => "EINVAL",
            Errno::EACCES => "EACCES",
            Errno::ESRCH => "ESRCH",
            _ => "refused",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cpu_ranges_parse_as_the_kernel_writes_them() {
        assert_eq!(parse_cpu_ranges("0-3,6"), Some(vec![0, 1, 2, 3, 6]));
        assert_eq!(parse_cpu_ranges("0"), Some(vec![0]));
        assert_eq!(parse_cpu_ranges("x"), None);
        assert!(!online_cpus().is_empty());
    }

    #[test]
    fn outcomes_read_back_through_the_pipe() {
        let asked = Scheduling {
            realtime_priority: Some(10),
            cpus: vec![0],
            nice: Some(5),
            lock_memory: true,
        };
        // Written by hand as the child would: nice applied, affinity EINVAL, FIFO EPERM.
        let pipe = OutcomePipe::new().expect("pipe");
        let mut bytes = [0u8; OUTCOME_BYTES];
        for (chunk, value) in
            bytes
                .chunks_exact_mut(4)
                .zip([APPLIED, Errno::EINVAL as i32, Errno::EPERM as i32])
        {
            chunk.copy_from_slice(&value.to_ne_bytes());
        }
        nix::unistd::write(&pipe.write, &bytes).expect("write");
        let outcome = pipe.read_outcome(&asked);
        assert_eq!(outcome.nice, CallOutcome::Applied);
        assert_eq!(outcome.affinity, CallOutcome::Refused(Errno::EINVAL));
        assert_eq!(outcome.realtime, CallOutcome::Refused(Errno::EPERM));
        assert_eq!(outcome.label(), "fifo10:EPERM cpu0:EINVAL nice5 mlock");
        let refusals = outcome.refusals();
        assert_eq!(refusals.len(), 2, "{refusals:?}");
        assert!(
            refusals[0].contains("SCHED_FIFO 10 refused (EPERM"),
            "{refusals:?}"
        );
        assert!(refusals[0].contains("at nice 5"), "{refusals:?}");
        assert!(refusals[0].contains("LimitRTPRIO=10"), "{refusals:?}");
    }

    #[test]
    fn a_child_that_never_reported_is_unknown() {
        let pipe = OutcomePipe::new().expect("pipe");
        let outcome = pipe.read_outcome(&Scheduling {
            realtime_priority: Some(1),
            ..Scheduling::default()
        });
        assert_eq!(outcome.realtime, CallOutcome::Unknown);
        assert_eq!(outcome.label(), "fifo1:?");
    }

    #[test]
    fn display_names_what_is_asked() {
        assert_eq!(Scheduling::default().to_string(), "default scheduling");
        let asked = Scheduling {
            realtime_priority: Some(80),
            cpus: vec![0, 1],
            nice: None,
            lock_memory: true,
        };
        assert_eq!(asked.to_string(), "SCHED_FIFO 80, CPUs 0,1, memory locked");
    }
}
