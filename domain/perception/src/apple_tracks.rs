//! Apples followed from frame to frame, so that what is learnt about one apple (a laser scan's
//! refined position) is applied to its later detections.
//!
//! The camera is fixed on the robot's frame and the apples hang still while the robot works, so
//! a detection belongs to the track whose last ToF position (robot frame) is nearest, within a
//! gate of a few centimetres (the ToF estimate of one apple moves by a few millimetres from frame
//! to frame). Pairs are assigned greedily, nearest first, one to one; unmatched detections start
//! new tracks; tracks unseen for `timeout_ns` are dropped (the apple was picked or left view).

/// What perception knows about one track's laser scan.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ScanState {
    /// No scan asked for.
    NotRequested,
    /// A scan was asked for and its answer has not come yet.
    Pending {
        request_seq: u32,
        /// Capture time of the frame that asked, ns.
        requested_ns: u64,
    },
    /// The scan answered with a position, kept for every later detection of the apple.
    Refined {
        position_in_camera_m: [f64; 3],
        position_in_robot_m: [f64; 3],
        request_seq: u32,
    },
    /// The scan gave no usable position (status, timeout or a position too far from the ToF
    /// estimate); the apple is not asked for again.
    Failed,
}

/// One apple followed over frames.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AppleTrack {
    /// Stable id, published as the detection's `apple_id`.
    pub id: u32,
    /// Latest ToF estimate of the centre, robot frame, m.
    pub position_in_robot_m: [f64; 3],
    pub radius_m: f64,
    /// Capture time of the last frame the apple was detected in, ns.
    pub last_seen_ns: u64,
    /// Frames the apple was detected in.
    pub frames_seen: u32,
    pub scan: ScanState,
    /// The laser found it out of its reach at least once (counted once per apple).
    pub out_of_laser_reach: bool,
}

/// The set of tracks with its association scratch.
#[derive(Debug, Clone, Default)]
pub struct AppleTracks {
    tracks: Vec<AppleTrack>,
    next_id: u32,
    pairs: Vec<(f64, usize, usize)>,
    track_taken: Vec<bool>,
}

impl AppleTracks {
    pub fn new() -> Self {
        Self::default()
    }

    pub fn tracks(&self) -> &[AppleTrack] {
        &self.tracks
    }

    pub fn get(&self, index: usize) -> Option<&AppleTrack> {
        self.tracks.get(index)
    }

    pub fn get_mut(&mut self, index: usize) -> Option<&mut AppleTrack> {
        self.tracks.get_mut(index)
    }

    /// The track with this id.
    pub fn by_id_mut(&mut self, id: u32) -> Option<&mut AppleTrack> {
        self.tracks.iter_mut().find(|track| track.id == id)
    }

    /// The track waiting for the scan `request_seq`.
    pub fn by_request_mut(&mut self, request_seq: u32) -> Option<&mut AppleTrack> {
        self.tracks.iter_mut().find(|track| {
            matches!(track.scan, ScanState::Pending { request_seq: seq, .. } if seq == request_seq)
        })
    }

    /// Associates this frame's detections (robot-frame centres and radii) with the tracks and
    /// writes the track index of each detection into `track_of` (same order). Matched tracks take
    /// the new position; the others start new tracks; tracks unseen for longer than
    /// `timeout_ns` before `now_ns` are dropped first.
    pub fn associate(
        &mut self,
        detections: impl ExactSizeIterator<Item = ([f64; 3], f64)> + Clone,
        now_ns: u64,
        gate_m: f64,
        timeout_ns: u64,
        track_of: &mut Vec<usize>,
    ) {
        self.tracks
            .retain(|track| now_ns.saturating_sub(track.last_seen_ns) <= timeout_ns);
        let count = detections.len();
        track_of.clear();
        track_of.resize(count, usize::MAX);
        self.pairs.clear();
        for (d, (position, _)) in detections.clone().enumerate() {
            for (t, track) in self.tracks.iter().enumerate() {
                let distance = distance_m(position, track.position_in_robot_m);
                if distance <= gate_m {
                    self.pairs.push((distance, d, t));
                }
            }
        }
        self.pairs
            .sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));
        self.track_taken.clear();
        self.track_taken.resize(self.tracks.len(), false);
        for &(_, d, t) in &self.pairs {
            if track_of[d] == usize::MAX && !self.track_taken[t] {
                track_of[d] = t;
                self.track_taken[t] = true;
            }
        }
        for (d, (position, radius_m)) in detections.enumerate() {
            let index = match track_of[d] {
                usize::MAX => {
                    self.tracks.push(AppleTrack {
                        id: self.next_id,
                        position_in_robot_m: position,
                        radius_m,
                        last_seen_ns: now_ns,
                        frames_seen: 0,
                        scan: ScanState::NotRequested,
                        out_of_laser_reach: false,
                    });
                    self.next_id = self.next_id.wrapping_add(1);
                    self.tracks.len() - 1
                }
                t => t,
            };
            track_of[d] = index;
            let track = &mut self.tracks[index];
            track.position_in_robot_m = position;
            track.radius_m = radius_m;
            track.last_seen_ns = now_ns;
            track.frames_seen = track.frames_seen.saturating_add(1);
        }
    }
}

/// Euclidean distance, m.
pub fn distance_m(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn associate(tracks: &mut AppleTracks, positions: &[[f64; 3]], now_ns: u64) -> Vec<u32> {
        let mut track_of = Vec::new();
        tracks.associate(
            positions.iter().map(|&p| (p, 0.04)),
            now_ns,
            0.03,
            1_000_000_000,
            &mut track_of,
        );
        track_of
            .iter()
            .map(|&t| tracks.get(t).expect("track").id)
            .collect()
    }

    #[test]
    fn the_same_apples_keep_their_ids_in_any_order() {
        let mut tracks = AppleTracks::new();
        let a = [1.2, 0.1, 0.8];
        let b = [1.25, -0.2, 0.9];
        let c = [1.3, 0.14, 0.8]; // 11 cm from a
        let first = associate(&mut tracks, &[a, b, c], 0);
        assert_eq!(first, vec![0, 1, 2]);
        // Next frame: a few millimetres of ToF noise, another order, one apple missing.
        let jitter = |p: [f64; 3], d: f64| [p[0] + d, p[1] - d, p[2]];
        let second = associate(
            &mut tracks,
            &[jitter(c, 0.004), jitter(a, -0.006)],
            33_000_000,
        );
        assert_eq!(second, vec![2, 0]);
        // A new apple far from every track gets a new id.
        let third = associate(
            &mut tracks,
            &[[0.9, 0.0, 0.5], jitter(b, 0.003)],
            66_000_000,
        );
        assert_eq!(third, vec![3, 1]);
        assert_eq!(tracks.tracks().len(), 4);
    }

    #[test]
    fn two_detections_near_one_track_do_not_share_it() {
        let mut tracks = AppleTracks::new();
        associate(&mut tracks, &[[1.0, 0.0, 0.8]], 0);
        // The nearer detection keeps the id; the other becomes a new apple.
        let ids = associate(&mut tracks, &[[1.02, 0.0, 0.8], [1.005, 0.0, 0.8]], 1);
        assert_eq!(ids, vec![1, 0]);
    }

    #[test]
    fn unseen_tracks_expire() {
        let mut tracks = AppleTracks::new();
        associate(&mut tracks, &[[1.0, 0.0, 0.8], [1.2, 0.0, 0.8]], 0);
        associate(&mut tracks, &[[1.0, 0.0, 0.8]], 600_000_000);
        // 1.5 s after the second apple was last seen: it is gone, the first stays.
        let ids = associate(&mut tracks, &[[1.0, 0.0, 0.8]], 1_500_000_000);
        assert_eq!(ids, vec![0]);
        assert_eq!(tracks.tracks().len(), 1);
    }
}
