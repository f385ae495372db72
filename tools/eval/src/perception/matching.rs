//! The rule that pairs reported apples with true apples.
//!
//! A detection `d` and a true apple `t` are a *candidate pair* when both hold:
//! 1. **2D overlap**: the detection's colour-image box holds at least
//!    `min_overlap_coefficient` (0.3) of `min(box area, visible pixels of t)` pixels labelled `t`
//!    by the simulator's label render (the overlap coefficient). A box around a fragment of an
//!    occluded apple passes because most of its pixels are that apple; a box around the whole
//!    apple passes because it holds most of the apple's visible pixels; a box on a neighbour does
//!    not.
//! 2. **3D gate**: the reported centre is within `max_distance_radii` (2.0) true radii of the
//!    true centre (robot frame).
//!
//! Candidate pairs are then assigned one to one, greedily in order of increasing 3D distance
//! (ties: lower detection index, then lower apple index). A matched detection is a true positive
//! and its 3D error is the distance; unmatched detections (including a second detection of an
//! already matched apple) are false positives; unmatched true apples are misses. The 3D gate is
//! much wider than the error targets (about 75 mm for a 37 mm apple), so the error statistics of
//! matched apples are not truncated near the targets. The same assignment without the 3D gate
//! ([`MatchRule::without_3d_gate`]) scores the detector alone ("found in 2D").

use serde::Serialize;

/// Parameters of the matching rule.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct MatchRule {
    /// Largest centre distance of a match, in true apple radii.
    pub max_distance_radii: f64,
    /// Smallest overlap coefficient `overlap / min(box area, visible pixels)` of a match.
    pub min_overlap_coefficient: f64,
}

impl MatchRule {
    /// The same rule without the 3D gate: scores the detector alone.
    pub fn without_3d_gate(self) -> Self {
        Self {
            max_distance_radii: f64::INFINITY,
            ..self
        }
    }
}

impl Default for MatchRule {
    fn default() -> Self {
        Self {
            max_distance_radii: 2.0,
            min_overlap_coefficient: 0.3,
        }
    }
}

/// A reported apple, as the matcher sees it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReportedApple {
    /// Reported centre, robot frame, metres.
    pub position_in_robot_m: [f64; 3],
    /// Area of the reported colour-image box, pixels.
    pub box_area_px: u64,
}

/// A true apple, as the matcher sees it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrueApple {
    /// True centre, robot frame, metres.
    pub center_in_robot_m: [f64; 3],
    pub radius_m: f64,
    /// Colour-image pixels labelled with this apple.
    pub visible_px: u64,
}

/// Pixels of each true apple inside each reported box: `overlap_px(d, t)`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct OverlapTable {
    truths: usize,
    px: Vec<u64>,
}

impl OverlapTable {
    /// A table of zeros for `detections` x `truths`, reusing the allocation.
    pub fn reset(&mut self, detections: usize, truths: usize) {
        self.truths = truths;
        self.px.clear();
        self.px.resize(detections * truths, 0);
    }

    /// Mutable row of detection `d` (one entry per true apple).
    pub fn row_mut(&mut self, d: usize) -> &mut [u64] {
        &mut self.px[d * self.truths..(d + 1) * self.truths]
    }

    pub fn get(&self, d: usize, t: usize) -> u64 {
        self.px.get(d * self.truths + t).copied().unwrap_or(0)
    }
}

/// Why a reported apple is a false positive.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FalsePositiveKind {
    /// It is a candidate of a true apple that another reported apple matched (an unmerged
    /// second detection of the same fruit).
    Duplicate,
    /// Its box overlaps a true apple enough, but its centre is beyond the 3D gate of every such
    /// apple (the detector found a fruit, the estimator misplaced it).
    Mislocalized,
    /// Its box overlaps no true apple enough (leaves, wood, background).
    NoApple,
}

/// Result of matching one frame.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Matching {
    /// For each reported apple, the index of its true apple and the 3D error in metres.
    pub truth_of_detection: Vec<Option<(usize, f64)>>,
    /// For each true apple, the index of its reported apple.
    pub detection_of_truth: Vec<Option<usize>>,
    /// Scratch list of candidate pairs `(distance, d, t)`.
    candidates: Vec<(f64, usize, usize)>,
}

impl Matching {
    pub fn true_positives(&self) -> usize {
        self.truth_of_detection.iter().flatten().count()
    }

    pub fn false_positives(&self) -> usize {
        self.truth_of_detection.len() - self.true_positives()
    }
}

fn distance_m(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

impl MatchRule {
    /// Whether `(d, t)` is a candidate pair; returns the centre distance in metres if so.
    pub fn candidate(
        &self,
        reported: &ReportedApple,
        truth: &TrueApple,
        overlap_px: u64,
    ) -> Option<f64> {
        let smaller_area = reported.box_area_px.min(truth.visible_px);
        if smaller_area == 0
            || (overlap_px as f64) < self.min_overlap_coefficient * smaller_area as f64
        {
            return None;
        }
        let distance = distance_m(reported.position_in_robot_m, truth.center_in_robot_m);
        (distance.is_finite() && distance <= self.max_distance_radii * truth.radius_m)
            .then_some(distance)
    }

    /// Classifies the unmatched reported apple `d` of a frame matched into `matching`; `None`
    /// when `d` is matched.
    pub fn false_positive_kind(
        &self,
        d: usize,
        reported: &[ReportedApple],
        truths: &[TrueApple],
        overlap: &OverlapTable,
        matching: &Matching,
    ) -> Option<FalsePositiveKind> {
        if matching
            .truth_of_detection
            .get(d)
            .copied()
            .flatten()
            .is_some()
        {
            return None;
        }
        let detection = reported.get(d)?;
        let overlapping = self.without_3d_gate();
        let mut kind = FalsePositiveKind::NoApple;
        for (t, truth) in truths.iter().enumerate() {
            let overlap_px = overlap.get(d, t);
            if self.candidate(detection, truth, overlap_px).is_some() {
                return Some(FalsePositiveKind::Duplicate);
            }
            if overlapping
                .candidate(detection, truth, overlap_px)
                .is_some()
            {
                kind = FalsePositiveKind::Mislocalized;
            }
        }
        Some(kind)
    }

    /// Matches `reported` to `truths` into `out` (allocations reused).
    pub fn match_frame(
        &self,
        reported: &[ReportedApple],
        truths: &[TrueApple],
        overlap: &OverlapTable,
        out: &mut Matching,
    ) {
        out.truth_of_detection.clear();
        out.truth_of_detection.resize(reported.len(), None);
        out.detection_of_truth.clear();
        out.detection_of_truth.resize(truths.len(), None);
        out.candidates.clear();
        for (d, detection) in reported.iter().enumerate() {
            for (t, truth) in truths.iter().enumerate() {
                if let Some(distance) = self.candidate(detection, truth, overlap.get(d, t)) {
                    out.candidates.push((distance, d, t));
                }
            }
        }
        out.candidates
            .sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));
        for &(distance, d, t) in &out.candidates {
            if out.truth_of_detection[d].is_none() && out.detection_of_truth[t].is_none() {
                out.truth_of_detection[d] = Some((t, distance));
                out.detection_of_truth[t] = Some(d);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const R: f64 = 0.04;

    fn truth(x: f64, y: f64, visible_px: u64) -> TrueApple {
        TrueApple {
            center_in_robot_m: [x, y, 0.5],
            radius_m: R,
            visible_px,
        }
    }

    fn reported(x: f64, y: f64, box_area_px: u64) -> ReportedApple {
        ReportedApple {
            position_in_robot_m: [x, y, 0.5],
            box_area_px,
        }
    }

    fn run(reported: &[ReportedApple], truths: &[TrueApple], overlaps: &[&[u64]]) -> Matching {
        let mut table = OverlapTable::default();
        table.reset(reported.len(), truths.len());
        for (d, row) in overlaps.iter().enumerate() {
            table.row_mut(d).copy_from_slice(row);
        }
        let mut out = Matching::default();
        MatchRule::default().match_frame(reported, truths, &table, &mut out);
        assert_eq!(out.true_positives() + out.false_positives(), reported.len());
        out
    }

    #[test]
    fn exact_detection_matches_with_its_error() {
        let out = run(
            &[reported(1.01, 0.0, 1000)],
            &[truth(1.0, 0.0, 700)],
            &[&[700]],
        );
        let (t, error) = out.truth_of_detection[0].expect("matched");
        assert_eq!(t, 0);
        assert!((error - 0.01).abs() < 1e-12);
        assert_eq!(out.detection_of_truth, vec![Some(0)]);
    }

    #[test]
    fn beyond_two_radii_is_a_false_positive_and_a_miss() {
        // 2.0 radii = 80 mm: 79 mm matches, 81 mm does not.
        let near = run(
            &[reported(1.079, 0.0, 1000)],
            &[truth(1.0, 0.0, 700)],
            &[&[700]],
        );
        assert_eq!(near.true_positives(), 1);
        let far = run(
            &[reported(1.081, 0.0, 1000)],
            &[truth(1.0, 0.0, 700)],
            &[&[700]],
        );
        assert_eq!(far.true_positives(), 0);
        assert_eq!(far.false_positives(), 1);
        assert_eq!(far.detection_of_truth, vec![None]);
    }

    #[test]
    fn without_2d_overlap_there_is_no_match() {
        // Right place in 3D, but the box holds only 20 % of the apple's 500 visible pixels.
        let out = run(
            &[reported(1.0, 0.0, 2000)],
            &[truth(1.0, 0.0, 500)],
            &[&[100]],
        );
        assert_eq!(out.true_positives(), 0);
        // 30 % of min(box 2000, visible 500) = 150 pixels is enough.
        let out = run(
            &[reported(1.0, 0.0, 2000)],
            &[truth(1.0, 0.0, 500)],
            &[&[150]],
        );
        assert_eq!(out.true_positives(), 1);
        // An apple with no visible pixel is never matched.
        let out = run(&[reported(1.0, 0.0, 2000)], &[truth(1.0, 0.0, 0)], &[&[0]]);
        assert_eq!(out.true_positives(), 0);
    }

    #[test]
    fn fragment_box_of_an_occluded_apple_matches() {
        // A 300-pixel box of which 250 pixels are the apple (which shows 1200 pixels in total).
        let out = run(
            &[reported(1.0, 0.0, 300)],
            &[truth(1.0, 0.0, 1200)],
            &[&[250]],
        );
        assert_eq!(out.true_positives(), 1);
    }

    #[test]
    fn duplicate_detection_is_a_false_positive() {
        let out = run(
            &[reported(1.02, 0.0, 900), reported(1.005, 0.0, 900)],
            &[truth(1.0, 0.0, 700)],
            &[&[600], &[600]],
        );
        // The nearer detection wins.
        assert_eq!(out.truth_of_detection[0], None);
        assert_eq!(out.truth_of_detection[1].map(|m| m.0), Some(0));
        assert_eq!(out.false_positives(), 1);
    }

    #[test]
    fn cluster_assignment_is_one_to_one_by_distance() {
        // Two touching apples 80 mm apart; detection 0 sits between them (nearer apple 1),
        // detection 1 sits on apple 1. Greedy by distance gives d1 -> t1, then d0 -> t0.
        let truths = [truth(1.0, 0.0, 800), truth(1.0, 0.08, 800)];
        let out = run(
            &[reported(1.0, 0.045, 2000), reported(1.0, 0.081, 900)],
            &truths,
            &[&[700, 700], &[0, 800]],
        );
        assert_eq!(out.truth_of_detection[1].map(|m| m.0), Some(1));
        assert_eq!(out.truth_of_detection[0].map(|m| m.0), Some(0));
        assert!((out.truth_of_detection[0].expect("matched").1 - 0.045).abs() < 1e-12);
        assert_eq!(out.detection_of_truth, vec![Some(0), Some(1)]);
    }

    #[test]
    fn without_the_3d_gate_only_overlap_counts() {
        let mut table = OverlapTable::default();
        table.reset(1, 1);
        table.row_mut(0)[0] = 700;
        let mut out = Matching::default();
        let far = [reported(3.3, 0.0, 1000)];
        let truths = [truth(1.0, 0.0, 700)];
        let rule = MatchRule::default();
        rule.match_frame(&far, &truths, &table, &mut out);
        assert_eq!(out.true_positives(), 0);
        rule.without_3d_gate()
            .match_frame(&far, &truths, &table, &mut out);
        assert_eq!(out.true_positives(), 1);
    }

    #[test]
    fn false_positives_are_classified() {
        let truths = [truth(1.0, 0.0, 700), truth(1.0, 0.3, 700)];
        let reported = [
            reported(1.005, 0.0, 900), // matches apple 0
            reported(1.02, 0.0, 900),  // second detection of apple 0
            reported(1.5, 0.3, 900),   // on apple 1 in 2D, 500 mm off in 3D
            reported(1.0, 0.6, 900),   // on nothing
        ];
        let overlaps: [&[u64]; 4] = [&[600, 0], &[600, 0], &[0, 600], &[0, 0]];
        let out = run(&reported, &truths, &overlaps);
        let mut table = OverlapTable::default();
        table.reset(reported.len(), truths.len());
        for (d, row) in overlaps.iter().enumerate() {
            table.row_mut(d).copy_from_slice(row);
        }
        let rule = MatchRule::default();
        let kinds: Vec<Option<FalsePositiveKind>> = (0..reported.len())
            .map(|d| rule.false_positive_kind(d, &reported, &truths, &table, &out))
            .collect();
        assert_eq!(
            kinds,
            vec![
                None,
                Some(FalsePositiveKind::Duplicate),
                Some(FalsePositiveKind::Mislocalized),
                Some(FalsePositiveKind::NoApple)
            ]
        );
    }

    #[test]
    fn no_detections_no_matches() {
        let out = run(&[], &[truth(1.0, 0.0, 800)], &[]);
        assert_eq!(out.detection_of_truth, vec![None]);
        assert_eq!(out.false_positives(), 0);
    }
}
