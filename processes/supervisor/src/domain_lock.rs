//! One stack per domain: `harvest up` holds an exclusive `flock(2)` on the domain's lock file
//! for as long as its stack runs, and refuses to start when another stack holds it.
//!
//! The file is `<iceoryx2 root>/harvest-up/<domain>.lock` (`/tmp/iceoryx2/harvest-up/` with the
//! stack's iceoryx2 configuration, beside the domain's service and node files; see
//! [`DomainLock::path`]). It holds the supervisor's pid, so the refusal names the running
//! supervisor. The kernel drops a `flock` when the last descriptor of its open file closes, so
//! a supervisor killed with SIGKILL leaves nothing stuck.
//!
//! The supervisor's children inherit the locked descriptor ([`DomainLock::inheritable_fd`]):
//! a stack counts as running while any of its processes runs. When the supervisor is killed,
//! its children get SIGTERM (parent-death signal) and stop; the next `harvest up` waits for
//! them (up to [`STOPPING_STACK_WAIT`]) instead of starting a second controller beside a
//! process of the old stack that is still commanding the robot.
//!
//! On a clean exit the file is removed while still locked; a starter that opened the removed
//! file notices (its file is no longer the one at the path) and opens the path again.

use harvest_ipc::Domain;
use nix::errno::Errno;
use nix::fcntl::{Flock, FlockArg};
use std::fs::{File, OpenOptions};
use std::io::{Read as _, Seek as _, Write as _};
use std::os::fd::{AsRawFd, RawFd};
use std::os::unix::fs::MetadataExt;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// How long `harvest up` waits for the processes of a stack whose supervisor is gone.
pub const STOPPING_STACK_WAIT: Duration = Duration::from_secs(15);
/// Between two attempts while waiting for a stopping stack (start-up only, not a hot path).
const RETRY_PERIOD: Duration = Duration::from_millis(50);
/// Folder of the lock files under the iceoryx2 root directory.
const LOCK_FOLDER: &str = "harvest-up";

/// The domain's lock, held by the running supervisor; released (and its file removed) on drop.
#[derive(Debug)]
pub struct DomainLock {
    file: Flock<File>,
    path: PathBuf,
}

/// `harvest up` cannot take the domain.
#[derive(Debug, thiserror::Error)]
pub enum DomainLockError {
    /// Another supervisor runs a stack in this domain.
    #[error(
        "a stack is already running in domain {domain:?}: `harvest up` with pid {pid} holds \
{path}. Stop it first (SIGINT or SIGTERM to pid {pid}), or use another --domain"
    )]
    Running {
        domain: String,
        pid: i32,
        path: PathBuf,
    },
    /// The supervisor that held the domain is gone, but processes of its stack still hold it.
    #[error(
        "domain {domain:?} is still held by processes {processes:?} of a stack whose \
`harvest up` ({holder}) is gone: they did not stop within {waited_s} s. Stop them, then start \
again (lock file {path})",
        holder = match pid { Some(pid) => format!("pid {pid}"), None => "pid unknown".to_owned() },
        waited_s = waited.as_secs_f64()
    )]
    Stopping {
        domain: String,
        pid: Option<i32>,
        /// Processes that have the lock file open (the old stack's).
        processes: Vec<i32>,
        path: PathBuf,
        waited: Duration,
    },
    #[error("domain lock file {path}: {action}: {source}")]
    Io {
        path: PathBuf,
        action: &'static str,
        source: std::io::Error,
    },
}

impl DomainLock {
    /// The lock file of `domain`: `<iceoryx2 root>/harvest-up/<domain>.lock`.
    pub fn path(domain: &Domain) -> PathBuf {
        let root = domain.iceoryx2_config().global.root_path().to_string();
        Path::new(&root)
            .join(LOCK_FOLDER)
            .join(format!("{}.lock", domain.name()))
    }

    /// Takes the lock of `domain` for this process, writing its pid into the file. Fails at
    /// once when a live supervisor holds it; waits up to `stopping_wait` for the processes of
    /// a stack whose supervisor died.
    pub fn acquire(domain: &Domain, stopping_wait: Duration) -> Result<Self, DomainLockError> {
        let path = Self::path(domain);
        let io = |action: &'static str| {
            let path = path.clone();
            move |source| DomainLockError::Io {
                path,
                action,
                source,
            }
        };
        if let Some(folder) = path.parent() {
            std::fs::create_dir_all(folder).map_err(io("creating its folder"))?;
        }
        let deadline = Instant::now() + stopping_wait;
        let mut waiting_logged = false;
        loop {
            let file = OpenOptions::new()
                .read(true)
                .write(true)
                .create(true)
                .truncate(false)
                .open(&path)
                .map_err(io("opening"))?;
            match Flock::lock(file, FlockArg::LockExclusiveNonblock) {
                Ok(mut file) => {
                    if !is_file_at(&file, &path) {
                        // The previous holder removed it between our open and our lock.
                        continue;
                    }
                    file.set_len(0).map_err(io("truncating"))?;
                    file.rewind().map_err(io("rewinding"))?;
                    writeln!(file, "{}", std::process::id()).map_err(io("writing the pid"))?;
                    file.flush().map_err(io("writing the pid"))?;
                    return Ok(Self { file, path });
                }
                Err((_, Errno::EWOULDBLOCK)) | Err((_, Errno::EINTR)) => {
                    let pid = holder_pid(&path);
                    if let Some(pid) = pid.filter(|pid| is_running(*pid)) {
                        return Err(DomainLockError::Running {
                            domain: domain.name().to_owned(),
                            pid,
                            path,
                        });
                    }
                    if Instant::now() >= deadline {
                        return Err(DomainLockError::Stopping {
                            domain: domain.name().to_owned(),
                            pid,
                            processes: processes_with_open(&path),
                            path,
                            waited: stopping_wait,
                        });
                    }
                    if !waiting_logged {
                        tracing::warn!(
                            domain = %domain,
                            supervisor_pid = ?pid,
                            wait_s = stopping_wait.as_secs(),
                            "the domain's previous supervisor is gone; waiting for its processes to stop"
                        );
                        waiting_logged = true;
                    }
                    std::thread::sleep(RETRY_PERIOD);
                }
                Err((_, errno)) => {
                    return Err(DomainLockError::Io {
                        path,
                        action: "locking",
                        source: errno.into(),
                    });
                }
            }
        }
    }

    /// The pid of the supervisor whose stack holds `domain`, if one does and it is alive
    /// (without taking the lock: a starting `harvest up` is not disturbed).
    pub fn running_supervisor(domain: &Domain) -> Option<i32> {
        let path = Self::path(domain);
        let file = File::open(&path).ok()?;
        match Flock::lock(file, FlockArg::LockSharedNonblock) {
            Ok(_unlocked_on_drop) => None,
            Err(_) => holder_pid(&path).filter(|pid| is_running(*pid)),
        }
    }

    /// The locked descriptor, for children to inherit (see the module documentation): while
    /// one of them runs, the domain stays held.
    pub fn inheritable_fd(&self) -> RawFd {
        self.file.as_raw_fd()
    }

    pub fn file_path(&self) -> &Path {
        &self.path
    }
}

impl Drop for DomainLock {
    fn drop(&mut self) {
        // Removed while still locked; `Flock` unlocks when the file is dropped after this.
        if is_file_at(&self.file, &self.path)
            && let Err(error) = std::fs::remove_file(&self.path)
        {
            tracing::debug!(path = %self.path.display(), %error, "could not remove the domain lock file");
        }
    }
}

/// Whether `file` is (still) the file at `path`.
fn is_file_at(file: &File, path: &Path) -> bool {
    match (file.metadata(), std::fs::metadata(path)) {
        (Ok(open), Ok(named)) => open.dev() == named.dev() && open.ino() == named.ino(),
        _ => false,
    }
}

/// The pid written by the holder (None while it is being written, or unreadable).
fn holder_pid(path: &Path) -> Option<i32> {
    let mut text = String::new();
    File::open(path).ok()?.read_to_string(&mut text).ok()?;
    text.lines().next()?.trim().parse().ok()
}

/// Processes other than this one with `path` open (from `/proc/<pid>/fd`; those this user
/// may inspect).
fn processes_with_open(path: &Path) -> Vec<i32> {
    let own = std::process::id() as i32;
    let mut pids: Vec<i32> = std::fs::read_dir("/proc")
        .into_iter()
        .flatten()
        .flatten()
        .filter_map(|entry| entry.file_name().to_str()?.parse::<i32>().ok())
        .filter(|pid| *pid != own)
        .filter(|pid| {
            std::fs::read_dir(format!("/proc/{pid}/fd"))
                .into_iter()
                .flatten()
                .flatten()
                .any(|fd| std::fs::read_link(fd.path()).is_ok_and(|target| target == path))
        })
        .collect();
    pids.sort_unstable();
    pids
}

/// Whether `pid` is a running process (not gone, not a zombie waiting to be reaped).
fn is_running(pid: i32) -> bool {
    if pid <= 0 {
        return false;
    }
    let exists = match nix::sys::signal::kill(nix::unistd::Pid::from_raw(pid), None) {
        Ok(()) | Err(Errno::EPERM) => true,
        Err(_) => false,
    };
    // `/proc/<pid>/stat`: "pid (comm) state ...": a zombie's state is Z.
    let zombie = std::fs::read_to_string(format!("/proc/{pid}/stat"))
        .ok()
        .and_then(|stat| {
            let after_comm = stat.rsplit_once(") ")?.1;
            after_comm.chars().next()
        })
        == Some('Z');
    exists && !zombie
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_second_lock_of_a_domain_is_refused_naming_the_holder() {
        let domain = harvest_ipc::ScratchDomain::new("lock");
        let first = DomainLock::acquire(&domain, Duration::ZERO).expect("first lock");
        assert!(first.file_path().starts_with("/tmp/iceoryx2/harvest-up"));
        let text = std::fs::read_to_string(first.file_path()).expect("lock file");
        assert_eq!(text.trim(), std::process::id().to_string());
        assert_eq!(
            DomainLock::running_supervisor(&domain),
            Some(std::process::id() as i32)
        );
        let error = DomainLock::acquire(&domain, Duration::from_secs(5)).expect_err("held");
        match &error {
            DomainLockError::Running { pid, .. } => assert_eq!(*pid, std::process::id() as i32),
            other => panic!("expected Running, got {other:?}"),
        }
        let message = error.to_string();
        assert!(
            message.contains(&std::process::id().to_string()),
            "{message}"
        );
        assert!(message.contains(domain.name()), "{message}");
        let path = first.file_path().to_owned();
        drop(first);
        assert!(!path.exists(), "a released lock leaves no file");
        assert_eq!(DomainLock::running_supervisor(&domain), None);
        let again = DomainLock::acquire(&domain, Duration::ZERO).expect("free again");
        drop(again);
    }

    #[test]
    fn a_holder_whose_pid_is_gone_is_waited_for_then_reported() {
        let domain = harvest_ipc::ScratchDomain::new("lockgone");
        let first = DomainLock::acquire(&domain, Duration::ZERO).expect("first lock");
        // What a killed supervisor leaves while a child still holds the inherited lock: a pid
        // that no longer runs (pid_max is at most 2^22 on Linux).
        std::fs::write(first.file_path(), "99999999\n").expect("rewrite pid");
        assert_eq!(DomainLock::running_supervisor(&domain), None);
        let error =
            DomainLock::acquire(&domain, Duration::from_millis(200)).expect_err("still held");
        assert!(
            matches!(
                error,
                DomainLockError::Stopping {
                    pid: Some(99999999),
                    ..
                }
            ),
            "{error:?}"
        );
        assert!(error.to_string().contains("99999999"), "{error}");
    }
}
