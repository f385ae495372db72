//! How fresh the frames perception works on are: the age of each frame when its processing
//! starts and the camera frames skipped since the previous one.
//!
//! Perception never queues frames behind a slow detector: it always takes the newest frame that
//! has arrived and drops the older ones (`Subscriber::receive_latest` in the process; frames the
//! camera channel's buffer overwrote while perception was busy are lost the same way). The cost of
//! a slow model is therefore skipped frames, never growing latency; this type makes that visible.
//! Skips are counted from the gaps in the camera's `msg_seq` between two processed frames, so they
//! include both the frames perception drained unprocessed and those the channel dropped.

/// The freshness of one processed frame.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FrameFreshness {
    /// Time from the frame's capture to the start of its processing, ns.
    pub age_ns: u64,
    /// Camera frames between the previous processed frame and this one that were not processed.
    pub skipped: u64,
}

/// Totals over the frames processed so far.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FreshnessTotals {
    pub frames: u64,
    pub skipped: u64,
    /// Largest age of a processed frame, ns.
    pub max_age_ns: u64,
    /// The last processed frame's freshness.
    pub last: FrameFreshness,
}

/// Follows the camera's `msg_seq` over the processed frames.
#[derive(Debug, Clone, Default)]
pub struct FreshnessTracker {
    last_seq: Option<u64>,
    totals: FreshnessTotals,
}

impl FreshnessTracker {
    /// Records that processing of frame `msg_seq`, captured at `capture_ns`, starts at `now_ns`
    /// (same clock). A sequence number at or below the previous one (a restarted camera) counts
    /// no skip.
    pub fn start_frame(&mut self, msg_seq: u64, capture_ns: u64, now_ns: u64) -> FrameFreshness {
        let skipped = match self.last_seq {
            Some(last) if msg_seq > last => msg_seq - last - 1,
            _ => 0,
        };
        self.last_seq = Some(msg_seq);
        let freshness = FrameFreshness {
            age_ns: now_ns.saturating_sub(capture_ns),
            skipped,
        };
        self.totals.frames += 1;
        self.totals.skipped += skipped;
        self.totals.max_age_ns = self.totals.max_age_ns.max(freshness.age_ns);
        self.totals.last = freshness;
        freshness
    }

    pub fn totals(&self) -> &FreshnessTotals {
        &self.totals
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gaps_in_the_camera_sequence_are_skipped_frames() {
        let mut tracker = FreshnessTracker::default();
        assert_eq!(
            tracker.start_frame(7, 1_000, 3_000),
            FrameFreshness {
                age_ns: 2_000,
                skipped: 0
            }
        );
        assert_eq!(tracker.start_frame(8, 2_000, 2_500).skipped, 0);
        assert_eq!(tracker.start_frame(12, 5_000, 9_000).skipped, 3);
        // A restarted camera (sequence back to 0) is no skip; a clock step is age 0.
        assert_eq!(
            tracker.start_frame(0, 10_000, 9_000),
            FrameFreshness {
                age_ns: 0,
                skipped: 0
            }
        );
        let totals = tracker.totals();
        assert_eq!(
            (totals.frames, totals.skipped, totals.max_age_ns),
            (4, 3, 4_000)
        );
    }
}
