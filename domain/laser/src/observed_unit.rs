//! An [`AlacsUnit`] wrapper that watches a scan go by: it calls a hook before every device
//! operation (the laser process sends its heartbeat there, since one scan blocks its loop for
//! several device exchanges) and records what the slide and the camera did, so the scan's
//! mechanical time can be modelled and its processing time separated from the device's.

use std::time::Instant;

use harvest_hw::alacs::{AlacsFrameInfo, AlacsUnit};
use harvest_ipc::camera_model::CameraIntrinsics;

/// What the device did during one scan.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ScanMotion {
    /// Slide moves commanded.
    pub moves: usize,
    /// Total slide travel, from the position before the scan, m.
    pub slide_travel_m: f64,
    /// Images captured.
    pub captures: usize,
    /// Capture stamp of each image, in capture order, ns (the unit's clock).
    pub capture_stamps_ns: Vec<u64>,
    /// Wall time spent inside the unit's calls (device exchanges, simulated rendering), ns.
    pub device_ns: u64,
}

impl ScanMotion {
    /// Forgets the last scan (keeps the stamp buffer's capacity).
    pub fn clear(&mut self) {
        self.moves = 0;
        self.slide_travel_m = 0.0;
        self.captures = 0;
        self.capture_stamps_ns.clear();
        self.device_ns = 0;
    }
}

/// Wraps `unit` for one scan; `before_step` runs before every operation.
pub struct ObservedUnit<'a, U: AlacsUnit> {
    unit: &'a mut U,
    before_step: &'a mut dyn FnMut(),
    motion: &'a mut ScanMotion,
    /// Encoder position after the last move, m (`None` until the first move of the scan).
    slide_position_m: Option<f64>,
}

impl<'a, U: AlacsUnit> ObservedUnit<'a, U> {
    /// `slide_position_m` is where the slide stands before the scan, if known (the travel of
    /// the first move counts from there; unknown counts the first move as no travel).
    pub fn new(
        unit: &'a mut U,
        slide_position_m: Option<f64>,
        before_step: &'a mut dyn FnMut(),
        motion: &'a mut ScanMotion,
    ) -> Self {
        motion.clear();
        Self {
            unit,
            before_step,
            motion,
            slide_position_m,
        }
    }

    /// Slide position after the last move, m.
    pub fn slide_position_m(&self) -> Option<f64> {
        self.slide_position_m
    }

    fn timed<T>(&mut self, call: impl FnOnce(&mut U) -> T) -> T {
        (self.before_step)();
        let started = Instant::now();
        let result = call(&mut *self.unit);
        self.motion.device_ns += started.elapsed().as_nanos() as u64;
        result
    }
}

impl<U: AlacsUnit> AlacsUnit for ObservedUnit<'_, U> {
    type Error = U::Error;

    fn intrinsics(&self) -> CameraIntrinsics {
        self.unit.intrinsics()
    }

    fn move_slide(&mut self, slide_position_m: f64) -> Result<f64, U::Error> {
        let settled_m = self.timed(|unit| unit.move_slide(slide_position_m))?;
        self.motion.moves += 1;
        if let Some(before_m) = self.slide_position_m {
            self.motion.slide_travel_m += (settled_m - before_m).abs();
        }
        self.slide_position_m = Some(settled_m);
        Ok(settled_m)
    }

    fn set_laser(&mut self, on: bool) -> Result<(), U::Error> {
        self.timed(|unit| unit.set_laser(on))
    }

    fn capture_rgb(&mut self, rgb: &mut [u8]) -> Result<AlacsFrameInfo, U::Error> {
        let info = self.timed(|unit| unit.capture_rgb(rgb))?;
        self.motion.captures += 1;
        self.motion.capture_stamps_ns.push(info.stamp_ns);
        Ok(info)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use harvest_sim::alacs::{AlacsScene, RenderedAlacs, RenderedAlacsConfig};

    #[test]
    fn records_travel_captures_and_hook_calls() {
        let intrinsics = CameraIntrinsics::from_horizontal_fov(64, 48, 45.0);
        let mut unit = RenderedAlacs::new(
            intrinsics,
            RenderedAlacsConfig::default(),
            AlacsScene::default(),
        )
        .expect("unit");
        let mut motion = ScanMotion::default();
        let mut steps = 0;
        let mut hook = || steps += 1;
        let mut observed = ObservedUnit::new(&mut unit, Some(0.05), &mut hook, &mut motion);
        let mut rgb = vec![0; 64 * 48 * 3];
        observed.set_laser(true).expect("laser");
        for target_m in [0.07, 0.08, 0.06] {
            observed.move_slide(target_m).expect("move");
            observed.capture_rgb(&mut rgb).expect("capture");
        }
        assert!(
            observed
                .slide_position_m()
                .is_some_and(|d| (d - 0.06).abs() < 1e-12)
        );
        assert_eq!(steps, 7);
        assert_eq!((motion.moves, motion.captures), (3, 3));
        // 0.05 -> 0.07 -> 0.08 -> 0.06: 2 + 1 + 2 cm.
        assert!((motion.slide_travel_m - 0.05).abs() < 1e-9, "{motion:?}");
        assert_eq!(motion.capture_stamps_ns.len(), 3);
        assert!(motion.capture_stamps_ns.windows(2).all(|w| w[0] < w[1]));
    }
}
