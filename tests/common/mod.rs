//! Helpers for the multi-process tests: unique domains, launch files, a watchdog on every child.

#![allow(dead_code)]

use std::io::Read;
use std::path::PathBuf;
use std::process::{Child, Command, ExitStatus, Stdio};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

pub mod console;
pub mod stack;
pub mod webdriver;

#[allow(unused_imports)]
pub use stack::*;

pub const HARVEST: &str = env!("CARGO_BIN_EXE_harvest");

/// The simulated robot's camera calibration, which perception needs (`--calibration`).
pub const SIM_CAMERA_CALIBRATION: &str =
    concat!(env!("CARGO_MANIFEST_DIR"), "/sim/camera_calibration.toml");

/// The test-only fault-injection fixture (`tests/fixtures/harvest_fixture.rs`, binary
/// `harvest-fixture`); launch files start it with `executable = ...`.
pub fn fixture_executable() -> String {
    env!("CARGO_BIN_EXE_harvest-fixture").to_owned()
}

/// Whole stacks render full-resolution frames: tests that run one take this lock so they do
/// not run at once on a 2-core machine (cargo runs a file's tests in parallel threads).
pub fn one_stack_at_a_time() -> std::sync::MutexGuard<'static, ()> {
    static LOCK: std::sync::Mutex<()> = std::sync::Mutex::new(());
    LOCK.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// A domain no other test (or concurrent run) uses; what its processes leave in /dev/shm is
/// removed when it is dropped (see [`harvest_ipc::ScratchDomain`]).
pub fn unique_domain(tag: &str) -> TestDomain {
    TestDomain(harvest_ipc::ScratchDomain::new(tag))
}

/// A test's domain, used as its name (`--domain`, `HARVEST_DOMAIN`).
#[derive(Debug)]
pub struct TestDomain(harvest_ipc::ScratchDomain);

impl TestDomain {
    pub fn domain(&self) -> &harvest_ipc::Domain {
        self.0.domain()
    }
}

impl std::ops::Deref for TestDomain {
    type Target = str;

    fn deref(&self) -> &str {
        self.0.name()
    }
}

impl AsRef<std::ffi::OsStr> for TestDomain {
    fn as_ref(&self) -> &std::ffi::OsStr {
        self.0.name().as_ref()
    }
}

impl std::fmt::Display for TestDomain {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.0.name())
    }
}

/// A scratch directory removed on drop.
pub struct TempDir(pub PathBuf);

impl TempDir {
    pub fn new(tag: &str) -> Self {
        let path = std::env::temp_dir().join(format!(
            "harvest-test-{tag}-{}",
            harvest_ipc::Domain::unique("d")
        ));
        std::fs::create_dir_all(&path).expect("create temp dir");
        Self(path)
    }

    pub fn write(&self, name: &str, text: &str) -> PathBuf {
        let path = self.0.join(name);
        std::fs::write(&path, text).expect("write file");
        path
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// The working directory of a test's `harvest` processes (recordings land here, not in the
/// checkout); removed by [`leftover_files`].
pub fn run_dir(domain: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("harvest-run-{domain}"));
    std::fs::create_dir_all(&dir).expect("create run dir");
    dir
}

/// Starts `harvest <args>` in `domain` with stderr captured.
pub fn spawn_harvest(domain: &str, args: &[&str]) -> Child {
    Command::new(HARVEST)
        .args(args)
        .current_dir(run_dir(domain))
        .env("HARVEST_DOMAIN", domain)
        .env("RUST_LOG", "info")
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn harvest")
}

/// Waits for `child` with a watchdog: after `limit` it is killed and the test fails.
pub fn wait_with_watchdog(mut child: Child, limit: Duration) -> (ExitStatus, String, String) {
    let deadline = Instant::now() + limit;
    let mut stderr_pipe = child.stderr.take().expect("stderr piped");
    let mut stdout_pipe = child.stdout.take().expect("stdout piped");
    let stderr_reader = std::thread::spawn(move || {
        let mut text = String::new();
        let _ = stderr_pipe.read_to_string(&mut text);
        text
    });
    let stdout_reader = std::thread::spawn(move || {
        let mut text = String::new();
        let _ = stdout_pipe.read_to_string(&mut text);
        text
    });
    let status = loop {
        if let Some(status) = child.try_wait().expect("try_wait") {
            break status;
        }
        if Instant::now() > deadline {
            let _ = child.kill();
            let _ = child.wait();
            let stderr = stderr_reader.join().unwrap_or_default();
            panic!("watchdog: harvest did not finish within {limit:?}; stderr:\n{stderr}");
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    let stderr = stderr_reader.join().unwrap_or_default();
    let stdout = stdout_reader.join().unwrap_or_default();
    (status, stdout, stderr)
}

/// A `harvest` child whose output is read from the start (a full pipe would block its
/// processes' logging and stall them while the test works). Killed on drop if still running
/// (a failed test leaves no stack behind: the supervisor's children get SIGTERM when it dies).
pub struct Drained {
    child: Child,
    stdout: Option<JoinHandle<String>>,
    stderr: Option<JoinHandle<String>>,
}

fn read_all(mut pipe: impl Read + Send + 'static) -> JoinHandle<String> {
    std::thread::spawn(move || {
        let mut text = String::new();
        let _ = pipe.read_to_string(&mut text);
        text
    })
}

impl Drained {
    pub fn spawn(domain: &str, args: &[&str]) -> Self {
        let mut child = spawn_harvest(domain, args);
        let stdout = read_all(child.stdout.take().expect("stdout piped"));
        let stderr = read_all(child.stderr.take().expect("stderr piped"));
        Self {
            child,
            stdout: Some(stdout),
            stderr: Some(stderr),
        }
    }

    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    /// SIGINT, then waits (killing the child after `limit`).
    pub fn interrupt_and_wait(self, limit: Duration) -> (ExitStatus, String, String) {
        self.signal(nix::sys::signal::Signal::SIGINT);
        self.wait(limit)
    }

    /// SIGKILL and reap: a crash of the process itself (its children are not signalled here).
    pub fn kill9_and_wait(self) -> (ExitStatus, String, String) {
        self.signal(nix::sys::signal::Signal::SIGKILL);
        self.wait(Duration::from_secs(10))
    }

    fn signal(&self, signal: nix::sys::signal::Signal) {
        let _ = nix::sys::signal::kill(nix::unistd::Pid::from_raw(self.child.id() as i32), signal);
    }

    /// Waits for the child to end, killing it after `limit`; returns its status and output.
    pub fn wait(mut self, limit: Duration) -> (ExitStatus, String, String) {
        let deadline = Instant::now() + limit;
        let status = loop {
            if let Some(status) = self.child.try_wait().expect("try_wait") {
                break status;
            }
            if Instant::now() > deadline {
                let _ = self.child.kill();
                let _ = self.child.wait();
                panic!("watchdog: harvest did not stop within {limit:?}");
            }
            std::thread::sleep(Duration::from_millis(50));
        };
        let stdout = self.stdout.take().map(|h| h.join().unwrap_or_default());
        let stderr = self.stderr.take().map(|h| h.join().unwrap_or_default());
        (
            status,
            stdout.unwrap_or_default(),
            stderr.unwrap_or_default(),
        )
    }
}

impl Drop for Drained {
    fn drop(&mut self) {
        if matches!(self.child.try_wait(), Ok(None)) {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}

/// Whether process `pid` still runs (gone and zombie processes do not).
pub fn process_running(pid: u32) -> bool {
    match std::fs::read_to_string(format!("/proc/{pid}/stat")) {
        Ok(stat) => stat
            .rsplit_once(") ")
            .and_then(|(_, rest)| rest.chars().next())
            .is_some_and(|state| state != 'Z'),
        Err(_) => false,
    }
}

/// Pids of the running children of `parent` (from `/proc/<pid>/stat`'s ppid field).
pub fn children_of(parent: u32) -> Vec<u32> {
    let mut children = Vec::new();
    for entry in std::fs::read_dir("/proc").into_iter().flatten().flatten() {
        let Ok(pid) = entry.file_name().to_string_lossy().parse::<u32>() else {
            continue;
        };
        let Ok(stat) = std::fs::read_to_string(format!("/proc/{pid}/stat")) else {
            continue;
        };
        let Some((_, rest)) = stat.rsplit_once(") ") else {
            continue;
        };
        let mut fields = rest.split_whitespace();
        let state = fields.next();
        let ppid = fields.next().and_then(|ppid| ppid.parse::<u32>().ok());
        if ppid == Some(parent) && state != Some("Z") {
            children.push(pid);
        }
    }
    children.sort_unstable();
    children
}

/// Runs `harvest <args>` to completion under a watchdog.
pub fn run_harvest(domain: &str, args: &[&str], limit: Duration) -> (ExitStatus, String, String) {
    wait_with_watchdog(spawn_harvest(domain, args), limit)
}

/// Runs `harvest up --launch <launch> --duration <duration>` in a fresh domain (`tag`) under a
/// watchdog of `limit`; asserts a clean exit that leaves no iceoryx2 file behind; returns
/// stderr (the supervisor's summary and the processes' logs).
pub fn run_up_for(tag: &str, launch: &std::path::Path, duration: &str, limit: Duration) -> String {
    let domain = unique_domain(tag);
    let launch = launch.to_str().expect("launch path is UTF-8");
    let (status, _, stderr) = run_harvest(
        &domain,
        &["up", "--launch", launch, "--duration", duration],
        limit,
    );
    assert!(status.success(), "{stderr}");
    assert_eq!(leftover_files(&domain), "", "{stderr}");
    stderr
}

/// The domain's iceoryx2 files still present (must be none after a clean exit). Also removes
/// the test's run directory and, through `harvest clean`, the domain's node registry in
/// /dev/shm once no node of the domain is left (so test runs do not pile up one file per
/// domain); `harvest clean` runs after the check, so the check still sees what the stack left.
pub fn leftover_files(domain: &str) -> String {
    let _ = std::fs::remove_dir_all(run_dir(domain));
    let leftovers = list_leftover_files(domain);
    let _ = Command::new(HARVEST)
        .arg("clean")
        .env("HARVEST_DOMAIN", domain)
        .output();
    leftovers
}

/// `harvest clean --check`: the domain's iceoryx2 files still present (listed, not removed).
pub fn list_leftover_files(domain: &str) -> String {
    let output = Command::new(HARVEST)
        .args(["clean", "--check"])
        .env("HARVEST_DOMAIN", domain)
        .output()
        .expect("run harvest clean --check");
    String::from_utf8_lossy(&output.stdout).into_owned()
}

/// Parses the `messages N` column of a process's line in `harvest up`'s final summary.
/// The number after `key ` in `harvest up`'s harvest summary line (stdout).
pub fn summary_count(stdout: &str, key: &str) -> Option<u32> {
    let line = stdout.lines().find(|l| l.starts_with("harvest summary:"))?;
    let start = line.find(&format!("{key} "))? + key.len() + 1;
    line[start..]
        .split(|c: char| !c.is_ascii_digit())
        .next()?
        .parse()
        .ok()
}

pub fn summary_messages(stderr: &str, process: &str) -> Option<u64> {
    let start = stderr.find("harvest up ended")?;
    stderr[start..].lines().find_map(|line| {
        let mut words = line.split_whitespace();
        if words.next()? != process {
            return None;
        }
        let words: Vec<&str> = line.split_whitespace().collect();
        let index = words.iter().position(|w| *w == "messages")?;
        words.get(index + 1)?.parse().ok()
    })
}

/// Parses the `restarts N` column of a process's line in the final summary.
pub fn summary_restarts(stderr: &str, process: &str) -> Option<u32> {
    let start = stderr.find("harvest up ended")?;
    stderr[start..].lines().find_map(|line| {
        let words: Vec<&str> = line.split_whitespace().collect();
        if words.first()? != &process {
            return None;
        }
        let index = words.iter().position(|w| *w == "restarts")?;
        words.get(index + 1)?.parse().ok()
    })
}
