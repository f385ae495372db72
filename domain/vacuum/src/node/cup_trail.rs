//! [`CupTrail`]: where an arm's cup carried an apple lately. A detection set reaches the node
//! after perception's latency, so an apple in a moving cup is seen where the cup was when the
//! frame was captured, not where it is when the set arrives: at a retract speed of 0.5 m/s,
//! 0.1 s of latency puts it 5 cm from the cup, beyond `held_margin_m`, and without the trail
//! it would be planned as a tree apple and attempted where nothing hangs.

/// Cup positions kept per arm: 128 node steps, 0.64 s at the 200 Hz control rate.
pub(super) const CUP_TRAIL_LEN: usize = 128;

/// A ring of `(stamp_ns, cup position in the robot frame, m)` of the steps in which the arm
/// carried an apple (see `holding_cup_m` in `planning.rs`); fixed size, no allocation.
#[derive(Debug, Clone, Copy)]
pub(super) struct CupTrail {
    points: [(u64, [f64; 3]); CUP_TRAIL_LEN],
    next: usize,
    len: usize,
}

impl Default for CupTrail {
    fn default() -> Self {
        Self {
            points: [(0, [0.0; 3]); CUP_TRAIL_LEN],
            next: 0,
            len: 0,
        }
    }
}

impl CupTrail {
    /// Records the cup at `stamp_ns`; the oldest point goes once the ring is full.
    pub(super) fn push(&mut self, stamp_ns: u64, cup_m: [f64; 3]) {
        self.points[self.next] = (stamp_ns, cup_m);
        self.next = (self.next + 1) % CUP_TRAIL_LEN;
        self.len = (self.len + 1).min(CUP_TRAIL_LEN);
    }

    /// The cup positions recorded at or after `from_ns`.
    pub(super) fn since(&self, from_ns: u64) -> impl Iterator<Item = &[f64; 3]> {
        self.points[..self.len]
            .iter()
            .filter(move |(stamp_ns, _)| *stamp_ns >= from_ns)
            .map(|(_, cup)| cup)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keeps_the_newest_points_and_filters_by_stamp() {
        let mut trail = CupTrail::default();
        assert_eq!(trail.since(0).count(), 0);
        for k in 0..(CUP_TRAIL_LEN as u64 + 10) {
            trail.push(k, [k as f64, 0.0, 0.0]);
        }
        assert_eq!(trail.since(0).count(), CUP_TRAIL_LEN);
        let recent: Vec<f64> = trail
            .since(CUP_TRAIL_LEN as u64 + 8)
            .map(|c| c[0])
            .collect();
        assert_eq!(recent.len(), 2);
        assert!(recent.contains(&(CUP_TRAIL_LEN as f64 + 9.0)));
        assert!(!recent.contains(&7.0));
    }
}
