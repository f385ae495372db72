//! The stack's processes as the kernel sees them: the supervisor's children (by the process
//! name the supervisor puts in their environment, `HARVEST_PROCESS_NAME`), their resident
//! memory, open descriptors and threads from `/proc`.

use serde::Serialize;
use std::collections::BTreeMap;
use std::path::Path;

use harvest_ipc::proc_status::status_field;

/// One process's figures at one instant.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct ProcessFigures {
    pub pid: u32,
    /// `VmRSS` of `/proc/<pid>/status`, KiB: private + file-backed + shared pages.
    pub rss_kib: u64,
    /// `RssAnon`, KiB: the process's private pages (heap, stacks). A leak grows this.
    pub private_kib: u64,
    /// `RssShmem`, KiB: pages of shared memory (iceoryx2's segments) this process has touched.
    /// It grows as a subscriber first reads pool slots it had not read before, up to the size of
    /// the segments it maps.
    pub shared_kib: u64,
    /// Entries of `/proc/<pid>/fd`.
    pub fds: u64,
    /// `Threads` of `/proc/<pid>/status`.
    pub threads: u64,
}

/// The launch names of the supervisor's children and their pids.
pub fn stack_children(supervisor_pid: u32) -> BTreeMap<String, u32> {
    let mut children = BTreeMap::new();
    let Ok(entries) = std::fs::read_dir("/proc") else {
        return children;
    };
    for entry in entries.flatten() {
        let Some(pid) = entry
            .file_name()
            .to_str()
            .and_then(|s| s.parse::<u32>().ok())
        else {
            continue;
        };
        if parent_pid(pid) != Some(supervisor_pid) {
            continue;
        }
        if let Some(name) = process_name(pid) {
            children.insert(name, pid);
        }
    }
    children
}

/// The parent pid from `/proc/<pid>/stat` (the field after the state, after the command in
/// parentheses, which may itself hold spaces and parentheses).
pub fn parent_pid(pid: u32) -> Option<u32> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    parse_parent_pid(&stat)
}

fn parse_parent_pid(stat: &str) -> Option<u32> {
    let after_command = &stat[stat.rfind(')')? + 1..];
    let mut fields = after_command.split_whitespace();
    let _state = fields.next()?;
    fields.next()?.parse().ok()
}

/// `HARVEST_PROCESS_NAME` from `/proc/<pid>/environ` (set by the supervisor for each child).
fn process_name(pid: u32) -> Option<String> {
    let environ = std::fs::read(format!("/proc/{pid}/environ")).ok()?;
    let key = format!("{}=", harvest_supervisor::child::PROCESS_NAME_ENV);
    environ
        .split(|&byte| byte == 0)
        .find_map(|entry| entry.strip_prefix(key.as_bytes()))
        .map(|name| String::from_utf8_lossy(name).into_owned())
}

/// The figures of `pid`, None when it is gone.
pub fn figures(pid: u32) -> Option<ProcessFigures> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let fds = std::fs::read_dir(format!("/proc/{pid}/fd")).ok()?.count() as u64;
    Some(ProcessFigures {
        pid,
        rss_kib: status_field(&status, "VmRSS:").unwrap_or(0),
        private_kib: status_field(&status, "RssAnon:").unwrap_or(0),
        shared_kib: status_field(&status, "RssShmem:").unwrap_or(0),
        fds,
        threads: status_field(&status, "Threads:").unwrap_or(0),
    })
}

/// Whether `pid` still exists (not yet reaped counts as existing).
pub fn exists(pid: u32) -> bool {
    Path::new(&format!("/proc/{pid}")).exists()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parent_pid_survives_parentheses_in_the_command() {
        let stat = "4242 (harvest (arm) x) S 17 4242 4242 0 -1 4194560 1 0";
        assert_eq!(parse_parent_pid(stat), Some(17));
        assert_eq!(parse_parent_pid("garbage"), None);
    }

    #[test]
    fn figures_of_this_process() {
        let me = figures(std::process::id()).expect("own /proc entry");
        assert!(me.rss_kib > 0 && me.fds > 0 && me.threads > 0, "{me:?}");
        assert!(me.private_kib > 0 && me.private_kib <= me.rss_kib, "{me:?}");
        assert_eq!(
            parent_pid(std::process::id()),
            Some(std::os::unix::process::parent_id())
        );
        assert!(exists(std::process::id()));
    }
}
