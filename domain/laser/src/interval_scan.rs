//! One interval scan ([alacs sec. 3]) as a sequence of device exchanges: the laser on, then
//! per image a slide move and a capture (each image turned into its candidate as it arrives),
//! then the laser off, also after a failed exchange; the selection at the end.
//!
//! [`IntervalScan`] makes no exchange itself: it says which one is next
//! ([`IntervalScan::next_exchange`]) and takes the unit's answer back, so that whoever holds
//! the unit makes it ([`exchange`]): [`drive`] runs a whole scan blocking on a unit
//! ([`crate::scan::run_scan`], [`crate::service::ScanService::answer`]), the laser's node makes
//! one exchange per tick ([`crate::task::LaserTask`]). A stopped scan
//! ([`IntervalScan::stop`]: the emergency stop switched the laser off) makes no further
//! exchange.

use std::time::Instant;

use harvest_hw::DeviceError;
use harvest_hw::alacs::{AlacsFrameInfo, AlacsUnit};
use harvest_ipc::camera_model::CameraIntrinsics;

use crate::candidate::{PositionCandidate, TargetHint};
use crate::scan::{ImageError, ScanError, ScanPlan, ScanProcessor, ScanResult};
use crate::scan_motion::ScanMotion;

/// One exchange with the ALACS unit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum UnitExchange {
    /// Switch the laser on (`true`) or off.
    SetLaser(bool),
    /// Move the slide to this position, m.
    MoveSlide(f64),
    /// Capture one RGB image.
    Capture,
}

/// The unit's answer to one exchange (a captured image is in the caller's buffer).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum UnitAnswer {
    /// The laser was switched.
    LaserSet,
    /// The slide settled here (the encoder's reading), m.
    SlideMoved { settled_m: f64 },
    /// An image was captured into the buffer.
    Captured { info: AlacsFrameInfo },
}

/// Bytes of one RGB8 image of `intrinsics`.
pub fn rgb_len(intrinsics: &CameraIntrinsics) -> usize {
    intrinsics.width_px as usize * intrinsics.height_px as usize * 3
}

/// Makes `exchange` on `unit`; a capture goes into `rgb` (one image, [`rgb_len`] bytes).
pub fn exchange<U: AlacsUnit>(
    unit: &mut U,
    exchange: UnitExchange,
    rgb: &mut [u8],
) -> Result<UnitAnswer, U::Error> {
    match exchange {
        UnitExchange::SetLaser(on) => unit.set_laser(on).map(|()| UnitAnswer::LaserSet),
        UnitExchange::MoveSlide(slide_position_m) => unit
            .move_slide(slide_position_m)
            .map(|settled_m| UnitAnswer::SlideMoved { settled_m }),
        UnitExchange::Capture => unit
            .capture_rgb(rgb)
            .map(|info| UnitAnswer::Captured { info }),
    }
}

/// Where a scan stands: the exchange it waits for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Stage {
    LaserOn,
    Move(usize),
    Capture(usize),
    LaserOff,
    Done,
}

/// One scan of one apple, exchange by exchange (module documentation). `E` is the unit's error.
#[derive(Debug)]
pub struct IntervalScan<E: DeviceError> {
    plan: ScanPlan,
    hint: TargetHint,
    stage: Stage,
    candidates: Vec<Result<PositionCandidate, ImageError>>,
    /// The first failure (a failed exchange, the stop); the scan switches the laser off and
    /// ends with it.
    failure: Option<ScanError<E>>,
    motion: ScanMotion,
    /// Encoder position after the last move, m (before the first: where the scan started, if
    /// known).
    slide_position_m: Option<f64>,
}

impl<E: DeviceError> IntervalScan<E> {
    /// A scan of `plan` for the target `hint`, the slide standing at `slide_position_m` (if
    /// known: the travel of the first move counts from there).
    pub fn new(plan: ScanPlan, hint: TargetHint, slide_position_m: Option<f64>) -> Self {
        Self {
            candidates: Vec::with_capacity(plan.slide_positions_m.len()),
            plan,
            hint,
            stage: Stage::LaserOn,
            failure: None,
            motion: ScanMotion::default(),
            slide_position_m,
        }
    }

    /// The exchange to make next; `None` once the scan has ended ([`Self::finish`]).
    pub fn next_exchange(&self) -> Option<UnitExchange> {
        match self.stage {
            Stage::LaserOn => Some(UnitExchange::SetLaser(true)),
            Stage::Move(k) => Some(UnitExchange::MoveSlide(self.plan.slide_positions_m[k])),
            Stage::Capture(_) => Some(UnitExchange::Capture),
            Stage::LaserOff => Some(UnitExchange::SetLaser(false)),
            Stage::Done => None,
        }
    }

    /// Whether the scan has ended.
    pub fn is_done(&self) -> bool {
        self.stage == Stage::Done
    }

    /// What the device did so far.
    pub fn motion(&self) -> &ScanMotion {
        &self.motion
    }

    /// Slide position after the last move, m.
    pub fn slide_position_m(&self) -> Option<f64> {
        self.slide_position_m
    }

    /// The unit answered the exchange asked for ([`Self::next_exchange`]) after `device_ns` in
    /// the exchange; a captured image (in `rgb`) is processed at once with `processor`. An
    /// answer that does not fit the exchange asked for is ignored (the exchange is asked again).
    pub fn answered(
        &mut self,
        answer: UnitAnswer,
        rgb: &[u8],
        device_ns: u64,
        processor: &mut ScanProcessor,
    ) {
        self.motion.device_ns += device_ns;
        tracing::trace!(stage = ?self.stage, ?answer, device_ns, "ALACS exchange answered");
        self.stage = match (self.stage, answer) {
            (Stage::LaserOn, UnitAnswer::LaserSet) => self.after_image(None),
            (Stage::Move(k), UnitAnswer::SlideMoved { settled_m }) => {
                self.motion.moves += 1;
                if let Some(before_m) = self.slide_position_m {
                    self.motion.slide_travel_m += (settled_m - before_m).abs();
                }
                self.slide_position_m = Some(settled_m);
                Stage::Capture(k)
            }
            (Stage::Capture(k), UnitAnswer::Captured { info }) => {
                self.motion.captures += 1;
                self.motion.capture_stamps_ns.push(info.stamp_ns);
                self.candidates.push(processor.process_image(
                    rgb,
                    info.slide_position_m,
                    &self.hint,
                ));
                self.after_image(Some(k))
            }
            (Stage::LaserOff, UnitAnswer::LaserSet) => Stage::Done,
            (stage, _) => stage,
        };
    }

    /// The stage after image `k` (`None`: before the first).
    fn after_image(&self, k: Option<usize>) -> Stage {
        let next = k.map_or(0, |k| k + 1);
        if next < self.plan.slide_positions_m.len() {
            Stage::Move(next)
        } else {
            Stage::LaserOff
        }
    }

    /// The exchange asked for failed after `device_ns`: the laser is switched off next (the
    /// scan ends with the first failure), or, if switching it off failed, the scan ends.
    pub fn failed(&mut self, error: E, device_ns: u64) {
        self.motion.device_ns += device_ns;
        tracing::trace!(stage = ?self.stage, %error, device_ns, "ALACS exchange failed");
        self.stage = match self.stage {
            Stage::Done => return,
            Stage::LaserOff => Stage::Done,
            Stage::LaserOn | Stage::Move(_) | Stage::Capture(_) => Stage::LaserOff,
        };
        self.failure.get_or_insert(ScanError::Device(error));
    }

    /// The emergency stop switched the laser off: the scan ends now, without another exchange,
    /// and fails with [`ScanError::Stopped`] (unless it had failed already).
    pub fn stop(&mut self) {
        if self.stage != Stage::Done {
            self.stage = Stage::Done;
            self.failure.get_or_insert(ScanError::Stopped);
        }
    }

    /// The scan's outcome once it has ended: the first failure, else the selected candidate
    /// ([`ScanProcessor::select`]). Call once; a scan that has not ended counts as stopped.
    pub fn finish(&mut self) -> Result<ScanResult, ScanError<E>> {
        self.stop();
        if let Some(failure) = self.failure.take() {
            return Err(failure);
        }
        let result = ScanProcessor::select(std::mem::take(&mut self.candidates))?;
        tracing::debug!(
            selected = result.selected,
            centre_in_camera_m = ?result.centre_in_camera_m,
            "ALACS scan done"
        );
        Ok(result)
    }
}

/// Runs `scan` to its end on `unit`, blocking for each exchange, with `rgb` as the image buffer
/// (resized to one image) and `before_step` called before every exchange (heartbeats).
pub fn drive<U: AlacsUnit>(
    scan: &mut IntervalScan<U::Error>,
    unit: &mut U,
    processor: &mut ScanProcessor,
    rgb: &mut Vec<u8>,
    before_step: &mut dyn FnMut(),
) {
    rgb.resize(rgb_len(&unit.intrinsics()), 0);
    while let Some(next) = scan.next_exchange() {
        before_step();
        let started = Instant::now();
        let result = exchange(unit, next, rgb);
        let device_ns = started.elapsed().as_nanos() as u64;
        match result {
            Ok(answer) => scan.answered(answer, rgb, device_ns, processor),
            Err(error) => scan.failed(error, device_ns),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::extraction::PixelRoi;
    use crate::scan::ProcessorConfig;
    use harvest_hw::alacs::AlacsExtrinsics;
    use harvest_sim::alacs::{AlacsScene, RenderedAlacs, RenderedAlacsConfig};

    fn setup() -> (RenderedAlacs, ScanProcessor, TargetHint) {
        let intrinsics = CameraIntrinsics::from_horizontal_fov(64, 48, 45.0);
        let unit = RenderedAlacs::new(
            intrinsics,
            RenderedAlacsConfig::default(),
            AlacsScene::default(),
        )
        .expect("unit");
        let processor = ScanProcessor::new(
            intrinsics,
            AlacsExtrinsics::paper_table1(),
            ProcessorConfig::default(),
        )
        .expect("processor");
        let hint = TargetHint {
            bbox_px: PixelRoi {
                u_min_px: 20,
                v_min_px: 14,
                u_max_px: 44,
                v_max_px: 34,
            },
            rough_centre_in_camera_m: [0.0, 0.0, 0.9],
        };
        (unit, processor, hint)
    }

    fn plan(slide_positions_m: Vec<f64>) -> ScanPlan {
        ScanPlan {
            plane_to_centre_m: vec![0.0; slide_positions_m.len()],
            slide_positions_m,
        }
    }

    #[test]
    fn records_travel_captures_and_hook_calls() {
        let (mut unit, mut processor, hint) = setup();
        let mut scan = IntervalScan::new(plan(vec![0.07, 0.08, 0.06]), hint, Some(0.05));
        let mut steps = 0;
        drive(
            &mut scan,
            &mut unit,
            &mut processor,
            &mut Vec::new(),
            &mut || steps += 1,
        );
        assert!(scan.is_done());
        assert!(
            scan.slide_position_m()
                .is_some_and(|d| (d - 0.06).abs() < 1e-12)
        );
        // Laser on, 3 x (move + capture), laser off.
        assert_eq!(steps, 8);
        let motion = scan.motion().clone();
        assert_eq!((motion.moves, motion.captures), (3, 3));
        // 0.05 -> 0.07 -> 0.08 -> 0.06: 2 + 1 + 2 cm.
        assert!((motion.slide_travel_m - 0.05).abs() < 1e-9, "{motion:?}");
        assert_eq!(motion.capture_stamps_ns.len(), 3);
        assert!(motion.capture_stamps_ns.windows(2).all(|w| w[0] < w[1]));
        // An empty scene: no image gave a candidate.
        assert!(matches!(scan.finish(), Err(ScanError::NoCandidate(_))));
    }

    #[test]
    fn a_failed_exchange_switches_the_laser_off_and_a_stop_ends_at_once() {
        let (_, mut processor, hint) = setup();
        let mut scan =
            IntervalScan::<harvest_hw::alacs::AlacsError>::new(plan(vec![0.05]), hint, None);
        assert_eq!(scan.next_exchange(), Some(UnitExchange::SetLaser(true)));
        scan.answered(UnitAnswer::LaserSet, &[], 0, &mut processor);
        assert_eq!(scan.next_exchange(), Some(UnitExchange::MoveSlide(0.05)));
        // An answer that does not fit is ignored.
        scan.answered(UnitAnswer::LaserSet, &[], 0, &mut processor);
        assert_eq!(scan.next_exchange(), Some(UnitExchange::MoveSlide(0.05)));
        scan.failed(
            harvest_hw::alacs::AlacsError::SlideOutOfStroke {
                requested_m: 0.05,
                stroke_m: 0.2,
            },
            0,
        );
        assert_eq!(scan.next_exchange(), Some(UnitExchange::SetLaser(false)));
        scan.answered(UnitAnswer::LaserSet, &[], 0, &mut processor);
        assert_eq!(scan.next_exchange(), None);
        assert!(matches!(scan.finish(), Err(ScanError::Device(_))));

        let mut stopped =
            IntervalScan::<harvest_hw::alacs::AlacsError>::new(plan(vec![0.05]), hint, None);
        stopped.answered(UnitAnswer::LaserSet, &[], 0, &mut processor);
        stopped.stop();
        assert_eq!(stopped.next_exchange(), None);
        assert!(matches!(stopped.finish(), Err(ScanError::Stopped)));
    }
}
