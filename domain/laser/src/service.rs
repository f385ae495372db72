//! Answering one scan request ([alacs sec. 3]): perception's rough apple position, given
//! in the ToF colour-camera frame, is moved into the ALACS camera frame with
//! [`ALACS_FROM_TOF_CAMERA`] (initialisation), the 5-image interval scan runs on any
//! [`AlacsUnit`], and the refined centre and every candidate are written back into a
//! [`LaserScanResult`] in the ToF colour-camera frame, the frame the request used.
//!
//! The refined centre is the sphere all the scan's stripe circles agree on ([`crate::fusion`])
//! when at least three images gave consistent circles, else the selected candidate
//! ([`crate::selection`]). A single candidate depends on the request's apple radius, which the
//! ToF camera measures only to a few millimetres; the fused sphere measures the radius itself.
//!
//! Transport-free: [`ScanService::answer`] scans blocking on any unit (`harvest eval laser`
//! with an in-process device); the laser's node ([`crate::task::LaserTask`]) scans one device
//! exchange per tick with the same pieces: [`ScanService::start`], [`ScanService::answered`]
//! for each exchange of the [`IntervalScan`], [`ScanService::complete`].
//!
//! [`ALACS_FROM_TOF_CAMERA`]: harvest_hw::alacs::ALACS_FROM_TOF_CAMERA

use std::time::Instant;

use harvest_hw::DeviceError;
use harvest_hw::alacs::{AlacsExtrinsics, AlacsUnit};
use harvest_ipc::camera_model::{CameraIntrinsics, RigidTransform};
use harvest_ipc::payloads::laser_scan::MAX_SCAN_CANDIDATES;
use harvest_ipc::payloads::{LaserScanRequest, LaserScanResult, LaserScanStatus};

use crate::candidate::PositionCandidate;
use crate::candidate::TargetHint;
use crate::extraction::ExtractionError;
use crate::fusion::{FusedSphere, FusionConfig, fuse_slices};
use crate::interval_scan::{IntervalScan, UnitAnswer, drive};
use crate::reach::{LaserReach, ReachError};
use crate::scan::{
    ProcessorConfig, ScanConfig, ScanError, ScanPlanError, ScanProcessor, ScanResult,
};
use crate::scan_motion::ScanMotion;

pub use crate::reach::FALLBACK_APPLE_RADIUS_M;

/// Why a request got no refined position.
#[derive(Debug, thiserror::Error)]
pub enum ScanRequestError<E: DeviceError> {
    /// The rough centre does not project into the ALACS image.
    #[error(
        "rough apple centre {centre_in_alacs_m:?} m (ALACS camera frame) is outside the camera's view"
    )]
    NotInView { centre_in_alacs_m: [f64; 3] },
    /// Planning, the device or the images failed.
    #[error(transparent)]
    Scan(#[from] ScanError<E>),
}

impl<E: DeviceError> ScanRequestError<E> {
    /// The `LaserScanResult::status` code of this failure.
    pub fn status(&self) -> LaserScanStatus {
        match self {
            Self::NotInView { .. } => LaserScanStatus::OutOfReach,
            Self::Scan(ScanError::Plan(
                ScanPlanError::OutOfReach { .. } | ScanPlanError::InvalidRoughCentre { .. },
            )) => LaserScanStatus::OutOfReach,
            Self::Scan(ScanError::Plan(ScanPlanError::InvalidConfig { .. }))
            | Self::Scan(ScanError::Device(_) | ScanError::Stopped) => LaserScanStatus::DeviceError,
            Self::Scan(ScanError::NoCandidate(_)) => LaserScanStatus::NoLaserLine,
        }
    }
}

/// The scan pipeline of one ALACS unit with its buffers (one image, the scan's motion).
#[derive(Debug)]
pub struct ScanService {
    reach: LaserReach,
    tof_from_alacs: RigidTransform,
    processor: ScanProcessor,
    rgb: Vec<u8>,
    motion: ScanMotion,
    slide_position_m: Option<f64>,
    fusion: FusionConfig,
    valid: Vec<PositionCandidate>,
    fused: Option<FusedSphere>,
}

impl ScanService {
    /// A service for a unit with `extrinsics` (eq. 7-8; from the calibration file) and camera
    /// `intrinsics`, mounted at `alacs_from_tof` relative to the ToF colour camera.
    pub fn new(
        extrinsics: AlacsExtrinsics,
        intrinsics: CameraIntrinsics,
        alacs_from_tof: RigidTransform,
    ) -> Result<Self, ExtractionError> {
        Ok(Self {
            reach: LaserReach::new(
                extrinsics,
                intrinsics,
                alacs_from_tof,
                ScanConfig::default(),
            ),
            tof_from_alacs: alacs_from_tof.inverse(),
            processor: ScanProcessor::new(intrinsics, extrinsics, ProcessorConfig::default())?,
            rgb: Vec::new(),
            motion: ScanMotion::default(),
            slide_position_m: None,
            fusion: FusionConfig::default(),
            valid: Vec::new(),
            fused: None,
        })
    }

    pub fn alacs_from_tof(&self) -> &RigidTransform {
        self.reach.alacs_from_tof()
    }

    /// The sphere the last scan's circles agreed on, if they did.
    pub fn last_fusion(&self) -> Option<&FusedSphere> {
        self.fused.as_ref()
    }

    /// What the device did during the last scan.
    pub fn last_motion(&self) -> &ScanMotion {
        &self.motion
    }

    /// The target as the scan sees it ([`LaserReach::hint`]).
    pub fn hint(&self, rough_centre_in_alacs_m: [f64; 3], radius_m: f64) -> Option<TargetHint> {
        self.reach.hint(rough_centre_in_alacs_m, radius_m)
    }

    /// The unit's reach model (the check [`Self::start`] makes before scanning).
    pub fn reach(&self) -> &LaserReach {
        &self.reach
    }

    /// Scans the apple of `request` on `unit` and writes the whole answer into `out` except the
    /// header's `msg_seq`/`publish_ns` (the publisher's): `capture_ns` is the capture stamp of
    /// the selected image (else of the last image, else 0), positions are in the ToF
    /// colour-camera frame, `candidates_in_camera_m[..candidate_count]` are the images that gave
    /// a candidate in scan order with their predicted standard error (m, smaller is better) as
    /// score, `selected` indexes the one the selection picked, and `position_in_camera_m` is the
    /// refined centre when `status` is 0 (the fused sphere, else the selected candidate; the
    /// returned [`ScanResult::centre_in_camera_m`] holds the same in the ALACS frame), else the
    /// request's rough position; `scan_duration_ns` is the wall time of the whole answer.
    /// `before_step` runs before every device exchange (heartbeats).
    pub fn answer<U: AlacsUnit>(
        &mut self,
        unit: &mut U,
        request: &LaserScanRequest,
        out: &mut LaserScanResult,
        before_step: &mut dyn FnMut(),
    ) -> Result<ScanResult, ScanRequestError<U::Error>> {
        let started = Instant::now();
        let scan = self.start(request).map(|mut scan| {
            drive(
                &mut scan,
                unit,
                &mut self.processor,
                &mut self.rgb,
                before_step,
            );
            scan
        });
        let outcome = self.complete(request, scan, out);
        out.scan_duration_ns = started.elapsed().as_nanos() as u64;
        outcome
    }

    /// The scan of `request`'s apple, to be driven exchange by exchange (answers through
    /// [`Self::answered`]) and then given to [`Self::complete`]; an apple out of view or reach
    /// (no exchange needed) is the error, to be given to [`Self::complete`] as well.
    pub fn start<E: DeviceError>(
        &self,
        request: &LaserScanRequest,
    ) -> Result<IntervalScan<E>, ScanRequestError<E>> {
        match self
            .reach
            .check(request.rough_position_in_camera_m, request.rough_radius_m)
        {
            Err(ReachError::NotInView { centre_in_alacs_m }) => {
                Err(ScanRequestError::NotInView { centre_in_alacs_m })
            }
            Err(ReachError::Plan(error)) => Err(ScanRequestError::Scan(ScanError::Plan(error))),
            Ok(in_reach) => Ok(IntervalScan::new(
                in_reach.plan,
                in_reach.hint,
                self.slide_position_m,
            )),
        }
    }

    /// The unit answered `scan`'s next exchange after `device_ns` (a captured image in `rgb`,
    /// processed at once): [`IntervalScan::answered`] with this service's image processor.
    pub fn answered<E: DeviceError>(
        &mut self,
        scan: &mut IntervalScan<E>,
        answer: UnitAnswer,
        rgb: &[u8],
        device_ns: u64,
    ) {
        scan.answered(answer, rgb, device_ns, &mut self.processor);
    }

    /// The answer to `request` once its scan ended (or could not start, `scan` being the error
    /// of [`Self::start`]): the outcome, fused when the scan's circles agree, written into `out`
    /// as [`Self::answer`] says except `scan_duration_ns` (the caller's clock). The scan's
    /// motion becomes [`Self::last_motion`].
    pub fn complete<E: DeviceError>(
        &mut self,
        request: &LaserScanRequest,
        scan: Result<IntervalScan<E>, ScanRequestError<E>>,
        out: &mut LaserScanResult,
    ) -> Result<ScanResult, ScanRequestError<E>> {
        self.fused = None;
        let outcome = match scan {
            Err(error) => {
                self.motion.clear();
                Err(error)
            }
            Ok(mut scan) => {
                self.slide_position_m = scan.slide_position_m();
                self.motion.clone_from(scan.motion());
                let extrinsics = self.reach.planner().extrinsics;
                scan.finish()
                    .map_err(ScanRequestError::from)
                    .map(|mut result| {
                        self.valid.clear();
                        self.valid
                            .extend(result.candidates.iter().filter_map(|c| c.as_ref().ok()));
                        self.fused = fuse_slices(&self.valid, &extrinsics, &self.fusion);
                        if let Some(fused) = &self.fused {
                            result.centre_in_camera_m = fused.centre_in_camera_m;
                        }
                        result
                    })
            }
        };
        self.write_result(request, &outcome, out);
        outcome
    }

    fn write_result<E: DeviceError>(
        &self,
        request: &LaserScanRequest,
        outcome: &Result<ScanResult, ScanRequestError<E>>,
        out: &mut LaserScanResult,
    ) {
        out.request_seq = request.request_seq;
        out.apple_id = request.apple_id;
        out._reserved = [0; 5];
        out.candidates_in_camera_m = [[0.0; 3]; MAX_SCAN_CANDIDATES];
        out.candidate_scores = [0.0; MAX_SCAN_CANDIDATES];
        out.candidate_count = 0;
        out.selected = 0;
        out.position_in_camera_m = request.rough_position_in_camera_m;
        let stamps = &self.motion.capture_stamps_ns;
        out.header.capture_ns = stamps.last().copied().unwrap_or(0);
        match outcome {
            Ok(result) => {
                out.status.set(LaserScanStatus::Ok);
                let mut count = 0;
                for (index, candidate) in result.candidates.iter().enumerate() {
                    let Ok(candidate) = candidate else {
                        continue;
                    };
                    if count == MAX_SCAN_CANDIDATES {
                        break;
                    }
                    if index == result.selected {
                        out.selected = count as u8;
                        if let Some(&stamp_ns) = stamps.get(index) {
                            out.header.capture_ns = stamp_ns;
                        }
                    }
                    out.candidates_in_camera_m[count] =
                        self.tof_from_alacs.apply(candidate.centre_in_camera_m);
                    out.candidate_scores[count] = candidate.predicted_sigma_m;
                    count += 1;
                }
                out.candidate_count = count as u8;
                out.position_in_camera_m = self.tof_from_alacs.apply(result.centre_in_camera_m);
            }
            Err(error) => out.status.set(error.status()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use harvest_hw::alacs::{ALACS_FROM_TOF_CAMERA, AlacsError, alacs_camera_intrinsics};
    use harvest_sim::alacs::{AlacsScene, AppleSphere, RenderedAlacs, RenderedAlacsConfig};

    fn service() -> ScanService {
        ScanService::new(
            AlacsExtrinsics::paper_table1(),
            alacs_camera_intrinsics(),
            ALACS_FROM_TOF_CAMERA,
        )
        .expect("service")
    }

    #[test]
    fn hint_box_matches_the_apparent_radius() {
        let service = service();
        let intrinsics = alacs_camera_intrinsics();
        let centre = [0.05, -0.02, 0.9];
        let hint = service.hint(centre, 0.04).expect("in view");
        let expected_px =
            intrinsics.fx_px * (0.04_f64 / 0.9_f64.hypot(0.05).hypot(0.02)).asin().tan();
        assert!((hint.radius_px() - expected_px).abs() <= 0.5, "{hint:?}");
        assert_eq!(hint.rough_centre_in_camera_m, centre);
        assert!(service.hint([2.0, 0.0, 0.9], 0.04).is_none());
        assert!(service.hint([0.0, 0.0, -0.9], 0.04).is_none());
    }

    #[test]
    fn answer_is_written_in_the_tof_frame() {
        let intrinsics = alacs_camera_intrinsics();
        let truth_in_alacs = [0.03, 0.02, 0.9];
        let scene = AlacsScene {
            apples: vec![AppleSphere {
                centre_in_camera_m: truth_in_alacs,
                radius_m: 0.04,
                rgb: [160, 35, 30],
            }],
            background_depth_m: Some(1.6),
            ..AlacsScene::default()
        };
        let mut unit =
            RenderedAlacs::new(intrinsics, RenderedAlacsConfig::default(), scene).expect("unit");
        let mut service = service();
        let tof_from_alacs = ALACS_FROM_TOF_CAMERA.inverse();
        let truth_in_tof = tof_from_alacs.apply(truth_in_alacs);
        let request = LaserScanRequest {
            request_seq: 11,
            apple_id: 4,
            // 1.2 cm off in depth along the ToF camera's axis, as a ToF estimate would be.
            rough_position_in_camera_m: tof_from_alacs.apply([
                truth_in_alacs[0] + 0.003,
                truth_in_alacs[1],
                truth_in_alacs[2] + 0.012,
            ]),
            rough_radius_m: 0.04,
            ..LaserScanRequest::default()
        };
        let mut out = LaserScanResult::default();
        let mut steps = 0;
        let result = service
            .answer(&mut unit, &request, &mut out, &mut || steps += 1)
            .expect("scan");
        assert_eq!(
            (out.request_seq, out.apple_id, out.status.get()),
            (11, 4, Ok(LaserScanStatus::Ok))
        );
        assert!(
            out.candidate_count >= 4 && out.selected < out.candidate_count,
            "{out:?}"
        );
        let error_m = (0..3)
            .map(|k| (out.position_in_camera_m[k] - truth_in_tof[k]).powi(2))
            .sum::<f64>()
            .sqrt();
        assert!(error_m < 3e-3, "{error_m} m: {out:?}");
        // Five clean circles: the fused sphere is the answer, and it measured the radius.
        let fused = *service.last_fusion().expect("fused");
        assert_eq!(fused.slices_used, 5);
        assert!((fused.radius_m - 0.04).abs() < 1e-3, "{fused:?}");
        let round_trip = ALACS_FROM_TOF_CAMERA.apply(out.position_in_camera_m);
        assert!((0..3).all(|k| (round_trip[k] - result.centre_in_camera_m[k]).abs() < 1e-12));
        assert_eq!(result.centre_in_camera_m, fused.centre_in_camera_m);
        // laser on + 5 x (move + capture) + laser off.
        assert_eq!(steps, 12);
        let motion = service.last_motion();
        assert_eq!((motion.moves, motion.captures), (5, 5));
        assert_eq!(
            out.header.capture_ns,
            motion.capture_stamps_ns[result.selected]
        );
    }

    #[test]
    fn apples_out_of_view_or_reach_get_status_two() {
        let intrinsics = alacs_camera_intrinsics();
        let mut unit = RenderedAlacs::new(
            intrinsics,
            RenderedAlacsConfig::default(),
            AlacsScene::default(),
        )
        .expect("unit");
        let mut service = service();
        let tof_from_alacs = ALACS_FROM_TOF_CAMERA.inverse();
        let mut out = LaserScanResult::default();
        for rough_in_alacs in [[0.0, 0.0, -1.0], [-0.3, 0.0, 1.0]] {
            let request = LaserScanRequest {
                rough_position_in_camera_m: tof_from_alacs.apply(rough_in_alacs),
                rough_radius_m: 0.04,
                ..LaserScanRequest::default()
            };
            let error = service
                .answer(&mut unit, &request, &mut out, &mut || {})
                .expect_err("out of reach");
            assert_eq!(error.status(), LaserScanStatus::OutOfReach, "{error}");
            assert_eq!(out.status, LaserScanStatus::OutOfReach);
            assert_eq!(out.position_in_camera_m, request.rough_position_in_camera_m);
            let _: &ScanRequestError<AlacsError> = &error;
        }
    }
}
