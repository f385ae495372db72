//! Laser refinement of hard apples without blocking the frame loop.
//!
//! Per frame, [`LaserRefiner::update`] follows the apples over frames ([`crate::apple_tracks`]),
//! applies to each apple the position a finished laser scan gave for it, and queues scan
//! requests for the apples [`crate::scan_policy`] selects. The process publishes the queued
//! requests on `laser/scan_request` and feeds every `laser/scan_result` to
//! [`LaserRefiner::handle_result`] whenever it arrives (a scan takes about 1.5 s, 30-45 frames):
//! the refined position is stored on the apple's track and used for all its later detections,
//! whose `method` then reads `LaserScan`.
//!
//! With the laser's reach model ([`LaserRefiner::set_reach`], the check the laser process
//! makes before it scans: [`harvest_laser::reach`]) only apples the unit can scan are asked
//! for; the others are counted ([`RefinerStats::out_of_laser_reach`], once per apple) and asked
//! for once they come into reach (the platform moved).
//!
//! A scan's position is accepted only when it lies within `max_refinement_shift_m` of the
//! apple's current ToF estimate (a larger jump means the line fell on another apple) and, unless
//! `accept_single_image_answers`, when it is the sphere fitted to all stripes rather than one
//! image's candidate (the result then equals its selected candidate, see the payload); a scan
//! that failed, was refused or went unanswered for `scan_timeout_ms` marks the apple as failed
//! and it is not asked for again.

use harvest_ipc::camera_model::RigidTransform;
use harvest_ipc::payloads::{LaserScanRequest, LaserScanResult, LaserScanStatus};
use harvest_laser::LaserReach;
use tracing::{debug, trace};

use crate::apple_tracks::{AppleTracks, ScanState, distance_m};
use crate::estimate_checks::visible_fraction;
use crate::pipeline::AppleEstimate;
use crate::scan_policy::{LaserScanConfig, ScanEvidence};

/// What perception publishes for one apple of the frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackedApple {
    /// The apple's track id (stable over frames).
    pub apple_id: u32,
    /// The laser scan's position when the apple has been refined: (camera frame, robot frame), m.
    pub laser_position_m: Option<([f64; 3], [f64; 3])>,
}

/// What happened to one scan result.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ScanResultOutcome {
    /// The apple's later detections take the scan's position.
    Refined,
    /// The scan reported a failure status.
    ScanFailed,
    /// The scan's position is not finite or too far from the ToF estimate.
    Refused,
    /// No apple waits for this request (its track expired, or it timed out).
    Unmatched,
}

/// Counters since start.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct RefinerStats {
    pub requests: u64,
    /// Apples the policy picked but the laser cannot reach (not asked for), each counted once.
    pub out_of_laser_reach: u64,
    pub refined: u64,
    pub scan_failures: u64,
    pub refused: u64,
    pub timed_out: u64,
    pub unmatched_results: u64,
    /// Detections published with a laser position.
    pub detections_refined: u64,
}

/// Tracks, scan policy and refined positions.
#[derive(Debug, Clone)]
pub struct LaserRefiner {
    config: LaserScanConfig,
    reach: Option<LaserReach>,
    tracks: AppleTracks,
    track_of: Vec<usize>,
    candidates: Vec<(f64, usize)>,
    requests: Vec<LaserScanRequest>,
    next_request_seq: u32,
    stats: RefinerStats,
}

impl LaserRefiner {
    /// `config` is validated with the rest of perception's config (pipeline setup).
    pub fn new(config: LaserScanConfig) -> Self {
        Self {
            config,
            reach: None,
            tracks: AppleTracks::new(),
            track_of: Vec::new(),
            candidates: Vec::new(),
            requests: Vec::new(),
            next_request_seq: 1,
            stats: RefinerStats::default(),
        }
    }

    pub fn config(&self) -> &LaserScanConfig {
        &self.config
    }

    /// Asks only for apples `reach` says the laser can scan (without: every apple the policy
    /// picks is asked for).
    pub fn set_reach(&mut self, reach: LaserReach) {
        self.reach = Some(reach);
    }

    pub fn reach(&self) -> Option<&LaserReach> {
        self.reach.as_ref()
    }

    pub fn stats(&self) -> &RefinerStats {
        &self.stats
    }

    pub fn tracks(&self) -> &AppleTracks {
        &self.tracks
    }

    /// Scan requests queued by the last [`Self::update`] (in the order to send them).
    pub fn requests(&self) -> &[LaserScanRequest] {
        &self.requests
    }

    /// Forgets the queued requests (they were sent, or the frame was rejected).
    pub fn clear_requests(&mut self) {
        self.requests.clear();
    }

    /// Scans asked for and not answered yet.
    pub fn pending_scans(&self) -> usize {
        self.tracks
            .tracks()
            .iter()
            .filter(|track| matches!(track.scan, ScanState::Pending { .. }))
            .count()
    }

    /// Follows this frame's `apples` (captured at `capture_ns`), writes what to publish for
    /// each into `out` (same order) and queues this frame's scan requests (replacing the
    /// previous frame's). `color_focal_px` sizes the apples' image discs.
    pub fn update(
        &mut self,
        apples: &[AppleEstimate],
        color_focal_px: f64,
        capture_ns: u64,
        out: &mut Vec<TrackedApple>,
    ) {
        self.requests.clear();
        out.clear();
        let config = self.config;
        self.tracks.associate(
            apples
                .iter()
                .map(|apple| (apple.position_in_robot_m, apple.radius_m)),
            capture_ns,
            config.track_gate_m,
            config.track_timeout_ms.saturating_mul(1_000_000),
            &mut self.track_of,
        );
        let scan_timeout_ns = config.scan_timeout_ms.saturating_mul(1_000_000);
        for index in 0..self.tracks.tracks().len() {
            let Some(track) = self.tracks.get_mut(index) else {
                continue;
            };
            if let ScanState::Pending { requested_ns, .. } = track.scan
                && capture_ns.saturating_sub(requested_ns) > scan_timeout_ns
            {
                debug!(apple_id = track.id, "laser scan timed out");
                track.scan = ScanState::Failed;
                self.stats.timed_out += 1;
            }
        }
        self.candidates.clear();
        for (apple_index, (apple, &track_index)) in apples.iter().zip(&self.track_of).enumerate() {
            let Some(track) = self.tracks.get(track_index) else {
                continue;
            };
            let laser_position_m = match track.scan {
                ScanState::Refined {
                    position_in_camera_m,
                    position_in_robot_m,
                    ..
                } if config.enabled => Some((position_in_camera_m, position_in_robot_m)),
                _ => None,
            };
            self.stats.detections_refined += u64::from(laser_position_m.is_some());
            out.push(TrackedApple {
                apple_id: track.id,
                laser_position_m,
            });
            if track.scan != ScanState::NotRequested {
                continue;
            }
            let evidence = ScanEvidence {
                visible_fraction: visible_fraction(
                    apple.visible_px,
                    apple.radius_m,
                    apple.position_in_camera_m[2],
                    color_focal_px,
                ),
                position_confidence: apple.position_confidence,
                fallback: apple.fallback,
            };
            let Some(priority) = config.scan_priority(&evidence) else {
                continue;
            };
            if let Some(reach) = &self.reach
                && let Err(why) = reach.check(apple.position_in_camera_m, apple.radius_m)
            {
                if let Some(track) = self.tracks.get_mut(track_index)
                    && !track.out_of_laser_reach
                {
                    track.out_of_laser_reach = true;
                    self.stats.out_of_laser_reach += 1;
                    debug!(apple_id = track.id, %why, "out of the laser's reach: not asked for");
                }
                continue;
            }
            self.candidates.push((priority, apple_index));
        }
        self.candidates
            .sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let free = (config.max_pending_scans as usize).saturating_sub(self.pending_scans());
        let budget = free.min(config.max_scans_per_frame as usize);
        for &(priority, apple_index) in self.candidates.iter().take(budget) {
            let (Some(apple), Some(&track_index)) =
                (apples.get(apple_index), self.track_of.get(apple_index))
            else {
                continue;
            };
            let Some(track) = self.tracks.get_mut(track_index) else {
                continue;
            };
            let request_seq = self.next_request_seq;
            self.next_request_seq = self.next_request_seq.wrapping_add(1).max(1);
            track.scan = ScanState::Pending {
                request_seq,
                requested_ns: capture_ns,
            };
            let mut request = LaserScanRequest {
                request_seq,
                apple_id: track.id,
                rough_position_in_camera_m: apple.position_in_camera_m,
                rough_radius_m: apple.radius_m,
                ..LaserScanRequest::default()
            };
            request.header.capture_ns = capture_ns;
            self.requests.push(request);
            self.stats.requests += 1;
            debug!(
                request_seq,
                apple_id = track.id,
                priority,
                position_in_camera_m = ?apple.position_in_camera_m,
                "laser scan requested"
            );
        }
        trace!(
            apples = apples.len(),
            tracks = self.tracks.tracks().len(),
            candidates = self.candidates.len(),
            requests = self.requests.len(),
            "laser refiner frame"
        );
    }

    /// Takes a scan's answer: stores the refined position on the apple that asked for it.
    /// `robot_from_camera` is the ToF colour camera's pose (the frame of the result).
    pub fn handle_result(
        &mut self,
        result: &LaserScanResult,
        robot_from_camera: &RigidTransform,
    ) -> ScanResultOutcome {
        let max_shift_m = self.config.max_refinement_shift_m;
        let accept_single_image = self.config.accept_single_image_answers;
        let Some(track) = self.tracks.by_request_mut(result.request_seq) else {
            self.stats.unmatched_results += 1;
            debug!(
                request_seq = result.request_seq,
                "laser scan result for no waiting apple"
            );
            return ScanResultOutcome::Unmatched;
        };
        // Any status but ok, an unknown code included, is a failed scan.
        if result.status != LaserScanStatus::Ok {
            track.scan = ScanState::Failed;
            self.stats.scan_failures += 1;
            debug!(
                apple_id = track.id,
                status = ?result.status,
                "laser scan failed"
            );
            return ScanResultOutcome::ScanFailed;
        }
        let position_in_camera_m = result.position_in_camera_m;
        let position_in_robot_m = robot_from_camera.apply(position_in_camera_m);
        let shift_m = distance_m(position_in_robot_m, track.position_in_robot_m);
        let single_image = is_single_image_answer(result);
        if !(position_in_camera_m.iter().all(|v| v.is_finite())
            && shift_m <= max_shift_m
            && (accept_single_image || !single_image))
        {
            track.scan = ScanState::Failed;
            self.stats.refused += 1;
            debug!(
                apple_id = track.id,
                shift_m, single_image, "laser scan position refused"
            );
            return ScanResultOutcome::Refused;
        }
        track.scan = ScanState::Refined {
            position_in_camera_m,
            position_in_robot_m,
            request_seq: result.request_seq,
        };
        self.stats.refined += 1;
        debug!(apple_id = track.id, shift_m, "apple refined by laser scan");
        ScanResultOutcome::Refined
    }
}

/// The scan answered with its selected single-image candidate instead of a sphere fitted to all
/// stripes (the payload's rule: the fused sphere when at least 3 stripes agree, else the selected
/// candidate).
pub fn is_single_image_answer(result: &LaserScanResult) -> bool {
    let count = usize::from(result.candidate_count).min(result.candidates_in_camera_m.len());
    let selected = usize::from(result.selected);
    count == 0
        || (selected < count
            && result.candidates_in_camera_m[selected] == result.position_in_camera_m)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::detector::PixelBox;
    use crate::estimator::EstimatorKind;

    const FOCAL_PX: f64 = 1000.0;

    /// An apple 1 m away of radius 4 cm (image disc of 40 px radius) with `visible_fraction` of
    /// its disc visible.
    fn apple(x_m: f64, visible_fraction: f64, position_confidence: f32) -> AppleEstimate {
        let disc_px = std::f64::consts::PI * 40.0 * 40.0;
        let position_in_camera_m = [x_m, 0.0, 1.0];
        AppleEstimate {
            pixel_box: PixelBox {
                u_min_px: 0,
                v_min_px: 0,
                u_max_px: 80,
                v_max_px: 80,
            },
            visible_px: (visible_fraction * disc_px) as u32,
            mask_confidence: 1.0,
            position_confidence,
            confidence: position_confidence,
            position_in_camera_m,
            position_in_robot_m: robot_from_camera().apply(position_in_camera_m),
            radius_m: 0.04,
            points_used: 100,
            estimator: EstimatorKind::SphereFit,
            fallback: false,
            detections_merged: 1,
        }
    }

    fn robot_from_camera() -> RigidTransform {
        RigidTransform {
            rotation: [[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]],
            translation_m: [0.0, 0.0, 0.9],
        }
    }

    /// A fused answer: five candidates around the fitted sphere's centre.
    fn answer(request: &LaserScanRequest, position_in_camera_m: [f64; 3]) -> LaserScanResult {
        let mut candidates = [position_in_camera_m; 5];
        for (k, candidate) in candidates.iter_mut().enumerate() {
            candidate[0] += 0.001 * (k as f64 - 2.0);
        }
        LaserScanResult {
            request_seq: request.request_seq,
            apple_id: request.apple_id,
            status: LaserScanStatus::Ok.into(),
            candidate_count: 5,
            selected: 1,
            position_in_camera_m,
            candidates_in_camera_m: candidates,
            ..LaserScanResult::default()
        }
    }

    /// The apple of [`apple`] moved to `position_in_camera_m`.
    fn apple_at(position_in_camera_m: [f64; 3]) -> AppleEstimate {
        AppleEstimate {
            position_in_camera_m,
            position_in_robot_m: robot_from_camera().apply(position_in_camera_m),
            ..apple(0.0, 0.3, 0.5)
        }
    }

    /// The laser's reach model (the check the laser process makes before scanning) keeps the
    /// apples it cannot scan out of the requests; they are counted once.
    #[test]
    fn only_apples_in_the_lasers_reach_are_asked_for() {
        use harvest_hw::alacs::{ALACS_FROM_TOF_CAMERA, AlacsExtrinsics, alacs_camera_intrinsics};
        use harvest_laser::{LaserReach, ReachError, ScanConfig};
        let reach = LaserReach::new(
            AlacsExtrinsics::paper_table1(),
            alacs_camera_intrinsics(),
            ALACS_FROM_TOF_CAMERA,
            ScanConfig::default(),
        );
        let tof_from_alacs = ALACS_FROM_TOF_CAMERA.inverse();
        let in_reach = tof_from_alacs.apply([0.03, 0.02, 0.9]);
        let beyond_stroke = (1..60)
            .flat_map(|k| [-0.02 * k as f64, 0.02 * k as f64])
            .map(|x| tof_from_alacs.apply([x, 0.0, 0.9]))
            .find(|centre| matches!(reach.check(*centre, 0.04), Err(ReachError::Plan(_))))
            .expect("an apple in view beyond the slide's stroke");
        let behind = tof_from_alacs.apply([0.0, 0.0, -0.9]);
        assert!(reach.check(in_reach, 0.04).is_ok());
        let apples = [
            apple_at(beyond_stroke),
            apple_at(in_reach),
            apple_at(behind),
        ];
        let config = LaserScanConfig {
            max_scans_per_frame: 3,
            max_pending_scans: 3,
            ..LaserScanConfig::default()
        };
        // Without the reach model all three are asked for.
        let mut unfiltered = LaserRefiner::new(config);
        let mut out = Vec::new();
        unfiltered.update(&apples, FOCAL_PX, 0, &mut out);
        assert_eq!(unfiltered.requests().len(), 3);
        let mut refiner = LaserRefiner::new(config);
        refiner.set_reach(reach);
        refiner.update(&apples, FOCAL_PX, 0, &mut out);
        let asked: Vec<u32> = refiner.requests().iter().map(|r| r.apple_id).collect();
        assert_eq!(asked, vec![1]);
        refiner.update(&apples, FOCAL_PX, 33_000_000, &mut out);
        assert!(refiner.requests().is_empty());
        assert_eq!(refiner.stats().requests, 1);
        assert_eq!(refiner.stats().out_of_laser_reach, 2);
    }

    #[test]
    fn the_policy_picks_the_occluded_and_uncertain_apples_most_uncertain_first() {
        let config = LaserScanConfig {
            max_scans_per_frame: 2,
            max_pending_scans: 3,
            ..LaserScanConfig::default()
        };
        let mut refiner = LaserRefiner::new(config);
        let apples = [
            apple(-0.3, 0.95, 0.9), // clear and confident: never scanned
            apple(-0.1, 0.45, 0.9), // heavily occluded
            apple(0.1, 0.9, 0.3),   // uncertain depth
            apple(0.3, 0.2, 0.5),   // both: most uncertain
        ];
        let mut out = Vec::new();
        refiner.update(&apples, FOCAL_PX, 0, &mut out);
        let ids: Vec<u32> = out.iter().map(|a| a.apple_id).collect();
        assert_eq!(ids, vec![0, 1, 2, 3]);
        let asked: Vec<u32> = refiner.requests().iter().map(|r| r.apple_id).collect();
        // Priority: visible fraction x confidence = 0.1 (apple 3), 0.27 (apple 2), 0.405 (1).
        assert_eq!(asked, vec![3, 2]);
        assert_eq!(
            refiner.requests()[0].rough_position_in_camera_m,
            [0.3, 0.0, 1.0]
        );
        // Next frame: one slot left of the 3 pending; the remaining candidate is asked for;
        // apples already asked for are not asked again.
        refiner.update(&apples, FOCAL_PX, 33_000_000, &mut out);
        let asked: Vec<u32> = refiner.requests().iter().map(|r| r.apple_id).collect();
        assert_eq!(asked, vec![1]);
        refiner.update(&apples, FOCAL_PX, 66_000_000, &mut out);
        assert!(refiner.requests().is_empty());
        assert_eq!(refiner.stats().requests, 3);
    }

    #[test]
    fn a_scan_result_refines_only_its_own_apple_in_later_frames() {
        let mut refiner = LaserRefiner::new(LaserScanConfig::default());
        let mut apples = vec![apple(-0.2, 0.9, 0.9), apple(0.2, 0.3, 0.9)];
        let mut out = Vec::new();
        refiner.update(&apples, FOCAL_PX, 0, &mut out);
        let request = refiner.requests()[0];
        assert_eq!(request.apple_id, 1);
        // While the scan runs, frames go on with the ToF positions.
        refiner.update(&apples, FOCAL_PX, 33_000_000, &mut out);
        assert!(out.iter().all(|a| a.laser_position_m.is_none()));
        let laser_in_camera = [0.205, 0.002, 1.012];
        let outcome =
            refiner.handle_result(&answer(&request, laser_in_camera), &robot_from_camera());
        assert_eq!(outcome, ScanResultOutcome::Refined);
        // Later frames, apples in another order and with ToF jitter: only apple 1 is refined.
        apples.reverse();
        apples[0].position_in_robot_m[0] += 0.004;
        refiner.update(&apples, FOCAL_PX, 1_500_000_000, &mut out);
        assert_eq!(out[0].apple_id, 1);
        let (camera, robot) = out[0].laser_position_m.expect("refined");
        assert_eq!(camera, laser_in_camera);
        assert_eq!(robot, robot_from_camera().apply(laser_in_camera));
        assert_eq!((out[1].apple_id, out[1].laser_position_m), (0, None));
        // A repeated or unknown answer changes nothing.
        assert_eq!(
            refiner.handle_result(&answer(&request, [0.0, 0.0, 1.0]), &robot_from_camera()),
            ScanResultOutcome::Unmatched
        );
        refiner.update(&apples, FOCAL_PX, 1_533_000_000, &mut out);
        assert_eq!(out[0].laser_position_m.expect("kept").0, laser_in_camera);
    }

    #[test]
    fn far_failed_or_late_answers_are_not_applied() {
        let config = LaserScanConfig {
            max_scans_per_frame: 4,
            max_pending_scans: 4,
            ..LaserScanConfig::default()
        };
        let mut refiner = LaserRefiner::new(config);
        let apples = [
            apple(-0.2, 0.3, 0.9),
            apple(0.0, 0.3, 0.9),
            apple(0.2, 0.3, 0.9),
            apple(0.4, 0.3, 0.9),
        ];
        let mut out = Vec::new();
        refiner.update(&apples, FOCAL_PX, 0, &mut out);
        let requests = refiner.requests().to_vec();
        assert_eq!(requests.len(), 4);
        // Answered by one image's candidate (no fused sphere): refused by default.
        let mut single = answer(&requests[3], [0.401, 0.0, 1.0]);
        single.candidates_in_camera_m[usize::from(single.selected)] = single.position_in_camera_m;
        assert!(is_single_image_answer(&single));
        assert_eq!(
            refiner.handle_result(&single, &robot_from_camera()),
            ScanResultOutcome::Refused
        );
        // 8 cm away from the ToF estimate: the line fell on something else.
        let far = answer(&requests[0], [-0.12, 0.0, 1.0]);
        assert_eq!(
            refiner.handle_result(&far, &robot_from_camera()),
            ScanResultOutcome::Refused
        );
        let failed = LaserScanResult {
            status: LaserScanStatus::NoLaserLine.into(),
            ..answer(&requests[1], [0.0, 0.0, 1.0])
        };
        assert_eq!(
            refiner.handle_result(&failed, &robot_from_camera()),
            ScanResultOutcome::ScanFailed
        );
        // The third is never answered: after the timeout the apple is given up.
        for second in 1..=6_u64 {
            refiner.update(&apples, FOCAL_PX, second * 1_000_000_000, &mut out);
        }
        assert!(out.iter().all(|a| a.laser_position_m.is_none()));
        assert!(
            refiner.requests().is_empty(),
            "failed apples are not asked again"
        );
        let late = answer(&requests[2], [0.2, 0.0, 1.0]);
        assert_eq!(
            refiner.handle_result(&late, &robot_from_camera()),
            ScanResultOutcome::Unmatched
        );
        let stats = refiner.stats();
        assert_eq!(
            (stats.refused, stats.scan_failures, stats.timed_out),
            (2, 1, 1)
        );
    }

    #[test]
    fn disabled_refiner_asks_nothing_but_keeps_ids() {
        let config = LaserScanConfig {
            enabled: false,
            ..LaserScanConfig::default()
        };
        let mut refiner = LaserRefiner::new(config);
        let apples = [apple(0.0, 0.1, 0.1), apple(0.2, 0.1, 0.1)];
        let mut out = Vec::new();
        refiner.update(&apples, FOCAL_PX, 0, &mut out);
        refiner.update(&apples, FOCAL_PX, 1, &mut out);
        assert!(refiner.requests().is_empty());
        assert_eq!(
            out.iter().map(|a| a.apple_id).collect::<Vec<_>>(),
            vec![0, 1]
        );
    }
}
