//! Figures of a process from Linux's `/proc/<pid>/status` (memory, locked pages, threads): one
//! reader for the memory lock's report, the soak's sampler and the tests' memory checks.

/// The first number after `key` (with its colon, e.g. `"RssAnon:"`) on its line of a
/// `/proc/<pid>/status` text: KiB for the memory lines, a count for `Threads:`.
pub fn status_field(status: &str, key: &str) -> Option<u64> {
    status
        .lines()
        .find_map(|line| line.strip_prefix(key))
        .and_then(|rest| rest.split_whitespace().next())
        .and_then(|value| value.parse().ok())
}

/// `key`'s figure of process `pid`; `None` when the process is gone or has no such line.
pub fn process_status_field(pid: u32, key: &str) -> Option<u64> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    status_field(&status, key)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn status_fields_are_read_by_key() {
        let status = "Name:\tharvest\nVmRSS:\t   12345 kB\nThreads:\t7\n";
        assert_eq!(status_field(status, "VmRSS:"), Some(12345));
        assert_eq!(status_field(status, "Threads:"), Some(7));
        assert_eq!(status_field(status, "VmLck:"), None);
        assert!(process_status_field(std::process::id(), "RssAnon:").is_some());
    }
}
