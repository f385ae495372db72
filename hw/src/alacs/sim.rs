//! The simulated ALACS unit as a device: the driver sends one [`AlacsCommand`] per operation on
//! `hw/alacs/command` (slide target, laser state, capture or not), the simulator moves its slide,
//! switches its laser, renders the image if asked and answers on `hw/alacs/image` with the same
//! `request_seq`, the way a real unit answers over its USB/serial links. The driver waits for that
//! answer event-driven (no polling) with a timeout, and copies the image into the caller's buffer
//! (the one device-to-driver transfer a real camera driver makes from its DMA buffer).
//!
//! Every operation is one bounded exchange. Answers to other requests (late answers to a request
//! that already timed out) are skipped.

use std::time::{Duration, Instant};

use harvest_ipc::camera_model::CameraIntrinsics;
use harvest_ipc::catalogue::{HW_ALACS_COMMAND, HW_ALACS_IMAGE};
use harvest_ipc::payloads::AlacsCommand;
use harvest_ipc::payloads::alacs::{ALACS_HEIGHT_PX, ALACS_RGB_BYTES, ALACS_WIDTH_PX};
use harvest_ipc::payloads::{AlacsImage, AlacsStatus};
use harvest_ipc::{Context, MonotonicClock, Publisher, Subscriber};

use super::error::{AlacsError, AlacsPart};
use super::extrinsics::{SLIDE_STROKE_M, check_slide_position};
use super::{AlacsFrameInfo, AlacsUnit};

/// Largest distance between the requested and the settled slide position the driver accepts,
/// m (the encoder's report; the conformance checks allow 1 mm).
pub const SLIDE_TOLERANCE_M: f64 = 1e-3;

/// Driver of the simulated ALACS unit.
///
/// The slide homes at `d = 0` on power-up: until the first answer reports its position, a
/// command that must not move the slide (laser switch, capture) targets the home position.
pub struct SimAlacsUnit {
    commands: Publisher<AlacsCommand>,
    images: Subscriber<AlacsImage>,
    intrinsics: CameraIntrinsics,
    timeout: Duration,
    last_request_seq: u32,
    laser_on: bool,
    /// Encoder position from the last answer, m; `None` before the first answer.
    slide_position_m: Option<f64>,
}

/// What the device answered to one command.
#[derive(Debug, Clone, Copy)]
struct Answer {
    stamp_ns: u64,
    slide_position_m: f64,
    laser_on: bool,
}

impl SimAlacsUnit {
    /// Opens the two hardware channels. Each later operation waits up to `timeout` for the
    /// device's answer (the simulator renders a 1440x1080 image per capture: allow for it).
    /// `intrinsics` is the camera the driver is configured for; the device's answers must carry
    /// the same, and the image channel fixes its size to 1440x1080.
    pub fn connect(
        context: &Context,
        intrinsics: CameraIntrinsics,
        timeout: Duration,
    ) -> Result<Self, AlacsError> {
        if intrinsics.width_px as usize != ALACS_WIDTH_PX
            || intrinsics.height_px as usize != ALACS_HEIGHT_PX
        {
            return Err(AlacsError::InvalidInput {
                what: format!(
                    "intrinsics {}x{} px (the hw/alacs/image channel carries {ALACS_WIDTH_PX}x{ALACS_HEIGHT_PX})",
                    intrinsics.width_px, intrinsics.height_px
                ),
            });
        }
        let link = |error: harvest_ipc::error::OpenChannelError| AlacsError::Disconnected {
            part: AlacsPart::Camera,
            detail: error.to_string(),
        };
        Ok(Self {
            commands: context.publisher(HW_ALACS_COMMAND).map_err(link)?,
            images: context
                .subscriber_with_buffer(HW_ALACS_IMAGE, 2)
                .map_err(link)?,
            intrinsics,
            timeout,
            last_request_seq: 0,
            laser_on: false,
            slide_position_m: None,
        })
    }

    /// Slide position the device last reported, m (`None` before its first answer).
    pub fn last_slide_position_m(&self) -> Option<f64> {
        self.slide_position_m
    }

    /// Sends one command and waits for its answer; with `rgb`, a capture whose image is copied
    /// into it (`rgb` holds exactly one image: the caller checked).
    fn exchange(
        &mut self,
        part: AlacsPart,
        slide_target_m: f64,
        rgb: Option<&mut [u8]>,
    ) -> Result<Answer, AlacsError> {
        self.last_request_seq = self.last_request_seq.wrapping_add(1).max(1);
        let request_seq = self.last_request_seq;
        let laser_on = u8::from(self.laser_on);
        let capture = u8::from(rgb.is_some());
        self.commands
            .publish_with(MonotonicClock::read_ns(), |command| {
                command.request_seq = request_seq;
                command.laser_on = laser_on;
                command.capture = capture;
                command._reserved = [0; 2];
                command.slide_target_m = slide_target_m;
            })
            .map_err(|error| AlacsError::Disconnected {
                part,
                detail: error.to_string(),
            })?;
        let started = Instant::now();
        let deadline = started + self.timeout;
        loop {
            while let Some(image) =
                self.images
                    .receive()
                    .map_err(|error| AlacsError::Disconnected {
                        part,
                        detail: error.to_string(),
                    })?
            {
                if image.request_seq != request_seq {
                    tracing::debug!(
                        got = image.request_seq,
                        expected = request_seq,
                        "skipping an ALACS answer to another request"
                    );
                    continue;
                }
                return self.accept(part, slide_target_m, &image, rgb);
            }
            let remaining = deadline.saturating_duration_since(Instant::now());
            let waited_ms = started.elapsed().as_millis() as u64;
            if remaining.is_zero() {
                return Err(AlacsError::Timeout { part, waited_ms });
            }
            // An interrupted wait (a signal arrived) ends the exchange like a timeout: the
            // caller's loop then sees the termination request.
            if let Err(error) = self.images.listener().timed_wait(|_| {}, remaining) {
                tracing::debug!(?error, "wait for the ALACS answer interrupted");
                return Err(AlacsError::Timeout { part, waited_ms });
            }
        }
    }

    /// Checks the answer to our request and takes its image.
    fn accept(
        &mut self,
        part: AlacsPart,
        slide_target_m: f64,
        image: &AlacsImage,
        rgb: Option<&mut [u8]>,
    ) -> Result<Answer, AlacsError> {
        match image.status.get() {
            Ok(AlacsStatus::Ok) => {}
            Ok(AlacsStatus::SlideOutOfStroke) => {
                return Err(AlacsError::SlideOutOfStroke {
                    requested_m: slide_target_m,
                    stroke_m: SLIDE_STROKE_M,
                });
            }
            Ok(AlacsStatus::DeviceFault) => {
                return Err(AlacsError::Fault {
                    part,
                    detail: format!("device reported a fault for request {}", image.request_seq),
                });
            }
            Err(unknown) => {
                return Err(AlacsError::Protocol {
                    part,
                    detail: format!("{unknown} in answer {}", image.request_seq),
                });
            }
        }
        if check_slide_position(image.slide_position_m).is_err() {
            return Err(AlacsError::Protocol {
                part: AlacsPart::Slide,
                detail: format!("reported slide position {} m", image.slide_position_m),
            });
        }
        self.slide_position_m = Some(image.slide_position_m);
        if let Some(rgb) = rgb {
            if image.has_image != 1 {
                return Err(AlacsError::Protocol {
                    part: AlacsPart::Camera,
                    detail: format!("answer {} to a capture carries no image", image.request_seq),
                });
            }
            if image.intrinsics != self.intrinsics {
                return Err(AlacsError::Protocol {
                    part: AlacsPart::Camera,
                    detail: format!(
                        "device camera {:?} differs from the configured {:?}",
                        image.intrinsics, self.intrinsics
                    ),
                });
            }
            rgb.copy_from_slice(&image.rgb);
        }
        Ok(Answer {
            stamp_ns: image.header.capture_ns,
            slide_position_m: image.slide_position_m,
            laser_on: image.laser_on != 0,
        })
    }

    /// Target that keeps the slide where it is.
    fn hold_position_m(&self) -> f64 {
        self.slide_position_m.unwrap_or(0.0)
    }
}

impl AlacsUnit for SimAlacsUnit {
    type Error = AlacsError;

    fn intrinsics(&self) -> CameraIntrinsics {
        self.intrinsics
    }

    fn move_slide(&mut self, slide_position_m: f64) -> Result<f64, AlacsError> {
        check_slide_position(slide_position_m)?;
        let answer = self.exchange(AlacsPart::Slide, slide_position_m, None)?;
        let settled_m = answer.slide_position_m;
        if (settled_m - slide_position_m).abs() > SLIDE_TOLERANCE_M {
            return Err(AlacsError::SlideMissedTarget {
                requested_m: slide_position_m,
                actual_m: settled_m,
                tolerance_m: SLIDE_TOLERANCE_M,
            });
        }
        tracing::trace!(
            requested_m = slide_position_m,
            settled_m,
            "ALACS slide settled"
        );
        Ok(settled_m)
    }

    fn set_laser(&mut self, on: bool) -> Result<(), AlacsError> {
        self.laser_on = on;
        let answer = self.exchange(AlacsPart::Laser, self.hold_position_m(), None)?;
        if answer.laser_on != on {
            return Err(AlacsError::Fault {
                part: AlacsPart::Laser,
                detail: format!(
                    "laser reported {} after switching it {}",
                    answer.laser_on, on
                ),
            });
        }
        Ok(())
    }

    fn capture_rgb(&mut self, rgb: &mut [u8]) -> Result<AlacsFrameInfo, AlacsError> {
        if rgb.len() != ALACS_RGB_BYTES {
            return Err(AlacsError::BufferSize {
                got_bytes: rgb.len(),
                needed_bytes: ALACS_RGB_BYTES,
                width_px: self.intrinsics.width_px,
                height_px: self.intrinsics.height_px,
            });
        }
        let answer = self.exchange(AlacsPart::Camera, self.hold_position_m(), Some(rgb))?;
        Ok(AlacsFrameInfo {
            stamp_ns: answer.stamp_ns,
            intrinsics: self.intrinsics,
            slide_position_m: answer.slide_position_m,
            laser_on: answer.laser_on,
        })
    }
}
