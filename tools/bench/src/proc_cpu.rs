//! A process's CPU time from `/proc/<pid>/stat`.

/// User + system CPU time of `pid`, seconds.
pub fn cpu_time_s(pid: u32) -> Result<f64, String> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat"))
        .map_err(|error| format!("/proc/{pid}/stat: {error}"))?;
    // Fields after the command name (which may hold spaces) start after the last ')'.
    let rest = stat.rsplit_once(')').map_or("", |(_, rest)| rest);
    let fields: Vec<&str> = rest.split_whitespace().collect();
    let ticks = |index: usize| fields.get(index).and_then(|v| v.parse::<u64>().ok());
    // utime and stime are fields 14 and 15 (1-based), 12 and 13 after the name and state.
    let (Some(utime), Some(stime)) = (ticks(11), ticks(12)) else {
        return Err(format!("/proc/{pid}/stat: {stat}"));
    };
    // /proc counts in USER_HZ, 100 on Linux whatever the kernel's tick.
    Ok((utime + stime) as f64 / 100.0)
}
