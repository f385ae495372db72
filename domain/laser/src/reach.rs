//! Which apples the ALACS unit can scan: the one reach check of the laser, used by the laser
//! process before it scans ([`crate::service::ScanService::start`]) and by perception before
//! it asks (the perception crate's laser refiner), so that no scan is requested that the
//! unit would answer "out of reach".
//!
//! An apple is in reach when its rough centre (ToF colour-camera frame, moved into the ALACS
//! camera frame with the unit's mounting) projects into the ALACS image
//! ([`LaserReach::hint`]), and the interval scan of [`crate::scan::ScanPlanner::plan`] fits the
//! slide's stroke (shifted by at most `max_shift_m`).

use harvest_hw::alacs::AlacsExtrinsics;
use harvest_ipc::camera_model::{CameraIntrinsics, RigidTransform};

use crate::candidate::TargetHint;
use crate::extraction::PixelRoi;
use crate::scan::{ScanConfig, ScanPlan, ScanPlanError, ScanPlanner};

/// Apple radius assumed when a request carries none usable (mean of the simulated orchard), m.
pub const FALLBACK_APPLE_RADIUS_M: f64 = 0.037;

/// Why an apple is out of the laser's reach.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ReachError {
    /// The rough centre does not project into the ALACS image.
    #[error(
        "rough apple centre {centre_in_alacs_m:?} m (ALACS camera frame) is outside the camera's view"
    )]
    NotInView { centre_in_alacs_m: [f64; 3] },
    /// No scan of the slide's stroke covers it (or the rough centre is unusable).
    #[error(transparent)]
    Plan(#[from] ScanPlanError),
}

/// What a scan of an apple in reach starts from.
#[derive(Debug, Clone, PartialEq)]
pub struct InReach {
    /// The target as the ALACS camera sees it.
    pub hint: TargetHint,
    /// Where the slide goes for each image.
    pub plan: ScanPlan,
}

/// The reach model of one ALACS unit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LaserReach {
    alacs_from_tof: RigidTransform,
    intrinsics: CameraIntrinsics,
    planner: ScanPlanner,
}

impl LaserReach {
    /// The unit with laser-camera `extrinsics` (its calibration), camera `intrinsics`, mounted
    /// at `alacs_from_tof` relative to the ToF colour camera, scanning with `scan`.
    pub fn new(
        extrinsics: AlacsExtrinsics,
        intrinsics: CameraIntrinsics,
        alacs_from_tof: RigidTransform,
        scan: ScanConfig,
    ) -> Self {
        Self {
            alacs_from_tof,
            intrinsics,
            planner: ScanPlanner {
                extrinsics,
                config: scan,
            },
        }
    }

    pub fn alacs_from_tof(&self) -> &RigidTransform {
        &self.alacs_from_tof
    }

    pub fn planner(&self) -> &ScanPlanner {
        &self.planner
    }

    /// Whether the unit can scan the apple of rough centre `rough_centre_in_tof_m` (ToF colour
    /// camera frame) and radius `radius_m` (a non-positive or non-finite radius stands for
    /// [`FALLBACK_APPLE_RADIUS_M`]); when it can, the hint and the slide positions.
    pub fn check(
        &self,
        rough_centre_in_tof_m: [f64; 3],
        radius_m: f64,
    ) -> Result<InReach, ReachError> {
        let centre_in_alacs_m = self.alacs_from_tof.apply(rough_centre_in_tof_m);
        let hint = self
            .hint(centre_in_alacs_m, radius_m)
            .ok_or(ReachError::NotInView { centre_in_alacs_m })?;
        let plan = self.planner.plan(centre_in_alacs_m)?;
        Ok(InReach { hint, plan })
    }

    /// The target as the scan sees it: the box the rough apple (centre in the ALACS camera frame,
    /// radius) covers in the ALACS image, and the rough centre. `None` when the centre does not
    /// project into the image.
    pub fn hint(&self, rough_centre_in_alacs_m: [f64; 3], radius_m: f64) -> Option<TargetHint> {
        let intrinsics = &self.intrinsics;
        let (u_px, v_px) = intrinsics.project(rough_centre_in_alacs_m)?;
        if !intrinsics.contains(u_px, v_px) {
            return None;
        }
        let radius_m = if radius_m.is_finite() && radius_m > 0.0 {
            radius_m
        } else {
            FALLBACK_APPLE_RADIUS_M
        };
        let distance_m = rough_centre_in_alacs_m
            .iter()
            .map(|c| c * c)
            .sum::<f64>()
            .sqrt();
        // Apparent radius of a sphere: its silhouette's half-angle is asin(R / distance).
        let radius_px = 0.5
            * (intrinsics.fx_px + intrinsics.fy_px)
            * (radius_m / distance_m).min(0.99).asin().tan();
        let corner =
            |centre_px: f64, sign: f64| (centre_px + sign * radius_px).round().max(0.0) as usize;
        Some(TargetHint {
            bbox_px: PixelRoi {
                u_min_px: corner(u_px, -1.0),
                v_min_px: corner(v_px, -1.0),
                u_max_px: corner(u_px, 1.0),
                v_max_px: corner(v_px, 1.0),
            },
            rough_centre_in_camera_m: rough_centre_in_alacs_m,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use harvest_hw::alacs::{ALACS_FROM_TOF_CAMERA, alacs_camera_intrinsics};

    fn reach() -> LaserReach {
        LaserReach::new(
            AlacsExtrinsics::paper_table1(),
            alacs_camera_intrinsics(),
            ALACS_FROM_TOF_CAMERA,
            ScanConfig::default(),
        )
    }

    #[test]
    fn an_apple_in_front_is_in_reach_and_one_beside_the_stroke_is_not() {
        let reach = reach();
        let tof_from_alacs = ALACS_FROM_TOF_CAMERA.inverse();
        let in_front = tof_from_alacs.apply([0.03, 0.02, 0.9]);
        let in_reach = reach.check(in_front, 0.04).expect("in reach");
        assert_eq!(in_reach.plan.slide_positions_m.len(), 5);
        // Behind the camera: not in view.
        assert!(matches!(
            reach.check(tof_from_alacs.apply([0.0, 0.0, -0.9]), 0.04),
            Err(ReachError::NotInView { .. })
        ));
        // Far to one side along the slide's travel, in the picture but beyond the stroke:
        // some lateral offset in view is out of the stroke.
        let beyond_stroke = (1..60)
            .map(|k| tof_from_alacs.apply([-0.02 * k as f64, 0.0, 0.9]))
            .chain((1..60).map(|k| tof_from_alacs.apply([0.02 * k as f64, 0.0, 0.9])))
            .find(|centre| {
                matches!(
                    reach.check(*centre, 0.04),
                    Err(ReachError::Plan(ScanPlanError::OutOfReach { .. }))
                )
            });
        assert!(
            beyond_stroke.is_some(),
            "no lateral offset in view runs off the stroke"
        );
    }
}
