//! Handing freed heap memory back to the kernel (`malloc_trim`), for long-running processes
//! whose threads allocate and free large transient buffers (a recording's chunks, a clip's
//! writer): glibc keeps freed pages of its per-thread arenas resident until the top of an arena
//! is free, so the resident size drifts with fragmentation rather than following what is in
//! use. Trimming after such work, and now and then, keeps a process's private memory flat.

/// Releases the free pages of every malloc arena to the kernel (`malloc_trim(0)`, which since
/// glibc 2.8 also returns whole free pages inside an arena, not only its top). Returns whether
/// any memory was released. Without glibc there is nothing to do: returns `false`.
pub fn release_freed_heap() -> bool {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        // SAFETY: `malloc_trim` takes no pointers; it walks glibc's arenas under their locks and
        // may be called from any thread at any time.
        let released = unsafe { nix::libc::malloc_trim(0) };
        released == 1
    }
    #[cfg(not(all(target_os = "linux", target_env = "gnu")))]
    {
        false
    }
}

/// [`release_freed_heap`] at most once a period, from a thread's loop.
#[derive(Debug, Clone)]
pub struct PeriodicHeapTrim {
    period: std::time::Duration,
    last: std::time::Instant,
}

impl PeriodicHeapTrim {
    /// The first trim comes one `period` from now.
    pub fn new(period: std::time::Duration) -> Self {
        Self {
            period,
            last: std::time::Instant::now(),
        }
    }

    /// Trims if a period has passed since the last trim; returns whether it trimmed.
    pub fn run_if_due(&mut self) -> bool {
        if self.last.elapsed() < self.period {
            return false;
        }
        self.last = std::time::Instant::now();
        let released = release_freed_heap();
        tracing::trace!(released, "heap trimmed");
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rss_anon_kib() -> u64 {
        crate::proc_status::process_status_field(std::process::id(), "RssAnon:").expect("RssAnon")
    }

    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    #[test]
    fn freed_memory_below_a_live_buffer_is_given_back() {
        // 192 MiB in 64 KiB buffers (below glibc's mmap threshold, so they come from the
        // arena), all freed but the last: the arena's top stays in use, so free() alone keeps
        // the pages resident; the trim hands them back.
        let mut buffers: Vec<Vec<u8>> = (0..3072).map(|i| vec![i as u8 | 1; 64 * 1024]).collect();
        let last = buffers.pop().expect("last");
        drop(buffers);
        let before_kib = rss_anon_kib();
        assert!(release_freed_heap(), "nothing released");
        let after_kib = rss_anon_kib();
        assert!(
            before_kib.saturating_sub(after_kib) >= 128 * 1024,
            "RssAnon {before_kib} -> {after_kib} KiB"
        );
        // The live buffer is intact and the heap still serves.
        assert!(last.iter().all(|&b| b == last[0]));
        let again = vec![7u8; 1 << 20];
        assert_eq!(again.iter().map(|&b| u64::from(b)).sum::<u64>(), 7 << 20);
    }
}
