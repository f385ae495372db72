//! A full recording disk, for real: the stack's recorder writes into a size-limited tmpfs until
//! it is full. The recorder finishes its file, reports itself degraded with "DISK FULL" in its
//! heartbeat and in `harvest up`'s status line, does not crash or restart, and the camera and
//! the arm keep running. Once space is freed it records into a new segment; when another
//! writer then fills the disk under it, it still finishes that segment (it holds the room to
//! finish ahead of what it writes). Every file reads back with the independent Python `mcap`
//! reader and with `harvest rec info`.
//!
//! Mounting needs root with CAP_SYS_ADMIN (CI runs as root). When a probe mount fails (not root,
//! or a container's root without the capability) the test runs itself again inside a user and
//! mount namespace (`unshare --user --map-root-user --mount`), where mounting a tmpfs is
//! allowed; either way the mount is removed at the end.

mod common;

use common::*;
use harvest_ipc::catalogue::PROCESS_HEALTH;
use harvest_ipc::payloads::ProcessRunState;
use harvest_ipc::{Context, Domain};
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// Set when the test runs inside the namespace it started itself.
const IN_NAMESPACE_ENV: &str = "HARVEST_TEST_IN_MOUNT_NAMESPACE";
const TEST_NAME: &str = "a_full_recording_disk_finishes_the_file_and_the_stack_goes_on";
/// Size of the recording file system: a few camera frames (6.8 MB each) fill it.
const DISK_SIZE_MIB: u32 = 64;
/// Taken by a file from the start and freed later, so the recorder finds room again.
const FREED_LATER_BYTES: usize = 40 << 20;

/// A size-limited tmpfs mounted on a fresh directory, unmounted and removed on drop.
struct SmallDisk {
    dir: PathBuf,
}

impl SmallDisk {
    fn mount(dir: PathBuf, size_mib: u32) -> Self {
        std::fs::create_dir_all(&dir).expect("create mount point");
        let output = Command::new("mount")
            .args(["-t", "tmpfs", "-o", &format!("size={size_mib}m"), "tmpfs"])
            .arg(&dir)
            .output()
            .expect("run mount");
        assert!(
            output.status.success(),
            "cannot mount a {size_mib} MiB tmpfs on {}: {}",
            dir.display(),
            String::from_utf8_lossy(&output.stderr)
        );
        Self { dir }
    }
}

impl Drop for SmallDisk {
    fn drop(&mut self) {
        let unmounted = Command::new("umount")
            .arg(&self.dir)
            .status()
            .is_ok_and(|status| status.success());
        if !unmounted {
            // Still busy (a process of a failed test): detach it now, it goes when unused.
            let _ = Command::new("umount").arg("-l").arg(&self.dir).status();
        }
        let _ = std::fs::remove_dir(&self.dir);
    }
}

fn launch(output_dir: &Path) -> String {
    format!(
        r#"
[stack]
hang_timeout_ms = 5000
shutdown_grace_ms = 5000
startup_grace_ms = 15000

[[process]]
name = "sim"
command = "sim"
args = ["--scenario", "default", "--seed", "1", "--camera-rate-hz", "2"]
restart = "never"

[[process]]
name = "camera"
command = "camera"
restart = "never"

[[process]]
name = "arm1"
command = "arm"
args = ["--id", "1"]
restart = "never"

# Uncompressed raw frames fill the small disk within seconds; 1 s between checks of the free space.
[[process]]
name = "recorder"
command = "recorder"
args = ["--output-dir", "{output_dir}", "--camera", "raw", "--compression", "none", "--chunk-size", "1MiB",
        "--split-size", "0", "--max-total-size", "0", "--retry-interval", "1s"]
restart = "never"
"#,
        output_dir = output_dir.display()
    )
}

/// Heartbeats of the stack's processes, newest per process.
struct Beats {
    latest: std::collections::BTreeMap<String, (ProcessRunState, u64, String)>,
}

impl Beats {
    fn take(&mut self, subscriber: &harvest_ipc::Subscriber<harvest_ipc::payloads::ProcessHealth>) {
        while let Ok(Some(beat)) = subscriber.receive() {
            if let Ok(state) = beat.run_state.get() {
                self.latest.insert(
                    beat.process_name.as_str().to_owned(),
                    (
                        state,
                        beat.main_channel_count,
                        beat.detail.as_str().to_owned(),
                    ),
                );
            }
        }
    }

    fn count(&self, process: &str) -> Option<u64> {
        self.latest.get(process).map(|(_, count, _)| *count)
    }
}

/// Waits (under a watchdog) until `done` holds for the latest beats.
fn wait_for_beats(
    subscriber: &harvest_ipc::Subscriber<harvest_ipc::payloads::ProcessHealth>,
    beats: &mut Beats,
    limit: Duration,
    what: &str,
    stderr: &Mutex<String>,
    done: impl Fn(&Beats) -> bool,
) {
    let deadline = Instant::now() + limit;
    loop {
        beats.take(subscriber);
        if done(beats) {
            return;
        }
        assert!(
            Instant::now() < deadline,
            "watchdog: {what} not seen within {limit:?}; last beats {:?}\nstderr:\n{}",
            beats.latest,
            stderr.lock().expect("lock")
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// The Python `mcap` reader's view of a file: whether it has a summary, messages per topic,
/// metadata record names.
fn python_read(path: &Path) -> serde_json::Value {
    const SCRIPT: &str = r#"
import json, sys
from mcap.reader import make_reader
out = {"has_summary": False, "messages": {}, "metadata": []}
with open(sys.argv[1], "rb") as f:
    reader = make_reader(f)
    out["has_summary"] = reader.get_summary() is not None
    for schema, channel, message in reader.iter_messages(log_time_order=False):
        out["messages"][channel.topic] = out["messages"].get(channel.topic, 0) + 1
    for record in reader.iter_metadata():
        out["metadata"].append(record.name)
print(json.dumps(out))
"#;
    python_json(SCRIPT, path)
}

#[test]
fn a_full_recording_disk_finishes_the_file_and_the_stack_goes_on() {
    if std::env::var_os(IN_NAMESPACE_ENV).is_none() && !can_mount_tmpfs() {
        run_in_user_and_mount_namespace();
        return;
    }
    let _stack = one_stack_at_a_time();
    let domain = unique_domain("dfull");
    let work = TempDir::new("diskfull");
    let disk = SmallDisk::mount(work.0.join("disk"), DISK_SIZE_MIB);
    let launch_file = work.write("launch.toml", &launch(&disk.dir));
    let freed_later = disk.dir.join("freed-later.bin");
    std::fs::write(&freed_later, vec![1u8; FREED_LATER_BYTES]).expect("write the filler");

    let mut child = spawn_harvest(
        &domain,
        &["up", "--launch", launch_file.to_str().expect("utf-8 path")],
    );
    let stderr = Arc::new(Mutex::new(String::new()));
    let stderr_thread = {
        let mut pipe = child.stderr.take().expect("stderr piped");
        let stderr = stderr.clone();
        std::thread::spawn(move || {
            let mut buffer = [0u8; 8192];
            while let Ok(read) = pipe.read(&mut buffer) {
                if read == 0 {
                    break;
                }
                stderr
                    .lock()
                    .expect("lock")
                    .push_str(&String::from_utf8_lossy(&buffer[..read]));
            }
        })
    };
    let stdout_thread = {
        let mut pipe = child.stdout.take().expect("stdout piped");
        std::thread::spawn(move || {
            let mut text = String::new();
            let _ = pipe.read_to_string(&mut text);
        })
    };

    {
        let context =
            Context::new(&Domain::new(&domain).expect("domain"), "test-health").expect("context");
        let health = context
            .subscriber_with_buffer(PROCESS_HEALTH, 256)
            .expect("health subscriber");
        let mut beats = Beats {
            latest: Default::default(),
        };
        let disk_full = |beats: &Beats| {
            beats
                .latest
                .get("recorder")
                .is_some_and(|(state, _, detail)| {
                    *state == ProcessRunState::Degraded && detail.starts_with("DISK FULL")
                })
        };
        // The recorder reports the full disk in its heartbeat.
        wait_for_beats(
            &health,
            &mut beats,
            Duration::from_secs(120),
            "the recorder's DISK FULL heartbeat",
            &stderr,
            disk_full,
        );
        // The stack goes on: frames and arm cycles keep coming after the disk filled.
        let frames_at_full = beats.count("camera").expect("camera beats");
        let arm_at_full = beats.count("arm1").expect("arm beats");
        wait_for_beats(
            &health,
            &mut beats,
            Duration::from_secs(60),
            "camera frames and arm ticks after the disk filled",
            &stderr,
            |beats| {
                beats
                    .count("camera")
                    .is_some_and(|n| n > frames_at_full + 3)
                    && beats.count("arm1").is_some_and(|n| n > arm_at_full + 100)
            },
        );
        // The recorder is still there, still saying so.
        assert!(disk_full(&beats), "{:?}", beats.latest.get("recorder"));
        // `harvest up`'s status line (printed every few seconds) shows it too.
        let deadline = Instant::now() + Duration::from_secs(60);
        loop {
            let text = stderr.lock().expect("lock").clone();
            if text.lines().any(|line| {
                line.trim_start().starts_with("recorder")
                    && line.contains("DEGRADED pid")
                    && line.contains("DISK FULL")
            }) {
                break;
            }
            assert!(
                Instant::now() < deadline,
                "watchdog: no status line shows the recorder's full disk:\n{text}"
            );
            std::thread::sleep(Duration::from_millis(200));
        }

        // Space comes back: the recorder resumes (within its retry interval).
        std::fs::remove_file(&freed_later).expect("free space");
        wait_for_beats(
            &health,
            &mut beats,
            Duration::from_secs(60),
            "the recorder resuming after space was freed",
            &stderr,
            |beats| {
                beats
                    .latest
                    .get("recorder")
                    .is_some_and(|(_, _, detail)| !detail.starts_with("DISK FULL"))
            },
        );
        // Another writer takes all the space: the recorder finishes its segment in the room
        // it holds.
        fill_up(&disk.dir.join("other-writer.bin"));
        wait_for_beats(
            &health,
            &mut beats,
            Duration::from_secs(60),
            "the recorder's DISK FULL heartbeat after another writer filled the disk",
            &stderr,
            disk_full,
        );
    }

    nix::sys::signal::kill(
        nix::unistd::Pid::from_raw(child.id() as i32),
        nix::sys::signal::Signal::SIGINT,
    )
    .expect("SIGINT harvest up");
    let deadline = Instant::now() + Duration::from_secs(60);
    let status = loop {
        if let Some(status) = child.try_wait().expect("try_wait") {
            break status;
        }
        if Instant::now() > deadline {
            let _ = child.kill();
            let _ = child.wait();
            panic!("watchdog: harvest up did not stop");
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    stderr_thread.join().expect("stderr reader");
    stdout_thread.join().expect("stdout reader");
    let stderr = stderr.lock().expect("lock").clone();
    assert!(status.success(), "harvest up failed:\n{stderr}");
    // No crash, no restart: the recorder ran until it was stopped.
    assert_eq!(summary_restarts(&stderr, "recorder"), Some(0), "{stderr}");
    let recorder_line = stderr
        .lines()
        .skip_while(|line| !line.contains("harvest up ended"))
        .find(|line| line.split_whitespace().next() == Some("recorder"))
        .unwrap_or_else(|| panic!("no summary line for the recorder:\n{stderr}"));
    assert!(
        recorder_line.contains("last exit: exit code 0"),
        "{recorder_line}"
    );
    assert!(stderr.contains("the recording disk is full"), "{stderr}");

    // Both segments were closed on a full disk, and both read back to their end.
    let files = mcap_files(&disk.dir);
    assert_eq!(files.len(), 2, "{files:?}\n{stderr}");
    for (index, file) in files.iter().enumerate() {
        let read = python_read(file);
        assert_eq!(read["has_summary"], true, "{}: {read}", file.display());
        if index == 0 {
            // (The second segment may have been cut off by the other writer before a frame.)
            let frames = read["messages"]["camera/rgbd"].as_u64().unwrap_or(0);
            let arm_states = read["messages"]["arm1/state"].as_u64().unwrap_or(0);
            assert!(frames > 0 && arm_states > 0, "{}: {read}", file.display());
        }
        let metadata: Vec<&str> = read["metadata"]
            .as_array()
            .expect("metadata list")
            .iter()
            .filter_map(|name| name.as_str())
            .collect();
        assert!(
            metadata.contains(&"harvest.disk_full"),
            "{}: {read}",
            file.display()
        );
        let (info_status, info, info_stderr) = run_harvest(
            &domain,
            &["rec", "info", file.to_str().expect("utf-8 path")],
            Duration::from_secs(60),
        );
        assert!(info_status.success(), "rec info failed: {info_stderr}");
        assert!(info.contains("complete (indexed)"), "{info}");
        assert!(info.contains("harvest.disk_full"), "{info}");
    }

    drop(disk);
    assert!(
        !work.0.join("disk").exists(),
        "the mount point was not removed"
    );
    assert_eq!(leftover_files(&domain), "");
}

/// Writes zeros into `path` until the file system is full.
fn fill_up(path: &Path) {
    use std::io::Write as _;
    let mut file = std::fs::File::create(path).expect("create the filler");
    let block = vec![0u8; 1 << 20];
    loop {
        match file.write_all(&block) {
            Ok(()) => {}
            Err(error) if error.kind() == std::io::ErrorKind::StorageFull => break,
            Err(error) => panic!("filling {}: {error}", path.display()),
        }
    }
    // What a partial last write left in the page cache fails to flush: the disk is full.
    let _ = file.flush();
}

/// Whether this process may mount a tmpfs here: root (effective user id 0, from
/// /proc/self/status) and a probe mount that succeeds.
fn can_mount_tmpfs() -> bool {
    let root = std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|status| {
            let uids = status
                .lines()
                .find(|line| line.starts_with("Uid:"))?
                .to_owned();
            uids.split_whitespace()
                .nth(2)
                .map(|effective| effective == "0")
        })
        .unwrap_or(false);
    if !root {
        return false;
    }
    let probe = TempDir::new("mount-probe");
    let mounted = Command::new("mount")
        .args(["-t", "tmpfs", "-o", "size=1m", "tmpfs"])
        .arg(&probe.0)
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|status| status.success());
    if mounted {
        let _ = Command::new("umount").arg(&probe.0).status();
    }
    mounted
}

/// Runs this test again inside a new user and mount namespace, where an unprivileged user may
/// mount a tmpfs (the namespace, and with it the mount, ends with the run).
fn run_in_user_and_mount_namespace() {
    let exe = std::env::current_exe().expect("test executable");
    let output = Command::new("unshare")
        .args(["--user", "--map-root-user", "--mount"])
        .arg(&exe)
        .args(["--exact", TEST_NAME, "--nocapture", "--test-threads=1"])
        .env(IN_NAMESPACE_ENV, "1")
        .stdin(Stdio::null())
        .output()
        .expect("run unshare (util-linux)");
    let stdout = String::from_utf8_lossy(&output.stdout);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        output.status.success() && stdout.contains("1 passed"),
        "the test inside `unshare --user --map-root-user --mount` failed (without root, user \
         namespaces must be allowed):\n{stdout}\n{stderr}"
    );
}
