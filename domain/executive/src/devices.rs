//! The executive's devices ([`ExecutiveDevices`]): the platform's stages and, along a row, the
//! tractor, both optional, behind their hardware traits; and the mode file a restarted
//! executive reads back.
//!
//! Reading: the platform is polled every [`PLATFORM_PERIOD_NS`] (every
//! [`SILENT_PLATFORM_PERIOD_NS`] after [`SILENT_AFTER`] failed polls in a row; at once after a
//! move was sent, since the stop cycle waits for the move to end); between polls the last view
//! is the reading. A failed poll is the read's error (the runner counts it and reports its
//! kind); the view is then unknown until a poll succeeds. The tractor is read every tick.
//!
//! Writing: the mode file and the tractor never make a write fail (a mode file not written is
//! logged; a tractor advance past the end of the row comes back in the next readings, so the
//! row's cycle ends the row there; another tractor failure is logged and the cycle sends the
//! advance again). A platform command the platform refuses or fails is the write's error: the
//! operator's command behind it is answered as refused.
//!
//! The stop (the emergency stop engaged, the end of the run): both stages and the tractor are
//! stopped, once per engagement.

use std::path::PathBuf;

use harvest_hw::platform::{Platform, PlatformTravel};
use harvest_hw::tractor::Tractor;
use harvest_hw::{AnyDeviceError, DeviceError, ErrorKind};
use harvest_ipc::payloads::OperatorModeCode;
use harvest_node::Devices;
use harvest_operator::mode_file::save_mode;
use harvest_operator::{ControlToken, PlatformView};

/// The platform is polled this often, ns.
pub const PLATFORM_PERIOD_NS: u64 = 100_000_000;
/// ... and this often once it failed [`SILENT_AFTER`] polls in a row, ns.
pub const SILENT_PLATFORM_PERIOD_NS: u64 = 1_000_000_000;
/// Failed polls in a row after which the platform counts as silent.
pub const SILENT_AFTER: u32 = 3;

/// Where the mode is kept for a restarted executive of the same run
/// ([`harvest_operator::mode_file`]).
#[derive(Debug, Clone)]
pub struct ModeStore {
    pub path: PathBuf,
    pub token: ControlToken,
}

/// One tick's readings.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ExecutiveReadings {
    /// The stages (`None`: no platform, or not known since a failed poll or a move sent).
    pub platform: Option<PlatformView>,
    /// The trailer along the row: position, m, and whether it moves (`None`: no tractor, or
    /// its read failed).
    pub tractor: Option<(f64, bool)>,
    /// The last tractor advance was refused as past the end of the row.
    pub tractor_past_end: bool,
}

/// A platform order.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PlatformOrder {
    MoveTo { target_m: [f64; 2] },
    Stop,
}

/// One tick's device commands.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ExecutiveCommands {
    pub platform: Option<PlatformOrder>,
    /// Advance the trailer by this much, m.
    pub tractor_advance_m: Option<f64>,
    /// Keep this mode and these enabled arms in the mode file.
    pub save_mode: Option<(OperatorModeCode, [bool; 2])>,
}

/// The executive's devices (module documentation).
#[derive(Debug)]
pub struct ExecutiveDevices<P, T> {
    platform: Option<P>,
    tractor: Option<T>,
    mode_store: Option<ModeStore>,
    /// The platform's last view, and when it was polled (`None`: poll at the next tick).
    platform_view: Option<PlatformView>,
    last_poll_ns: Option<u64>,
    failed_polls: u32,
    tractor_past_end: bool,
    /// The stop was sent and nothing written since.
    stopped: bool,
}

impl<P: Platform, T: Tractor> ExecutiveDevices<P, T> {
    pub fn new(platform: Option<P>, tractor: Option<T>, mode_store: Option<ModeStore>) -> Self {
        Self {
            platform,
            tractor,
            mode_store,
            platform_view: None,
            last_poll_ns: None,
            failed_polls: 0,
            tractor_past_end: false,
            stopped: false,
        }
    }

    /// The platform's driver, if any.
    pub fn platform(&self) -> Option<&P> {
        self.platform.as_ref()
    }

    pub fn platform_present(&self) -> bool {
        self.platform.is_some()
    }

    /// The travel of the stages (the default's when there is no platform).
    pub fn platform_travel(&self) -> PlatformTravel {
        self.platform
            .as_ref()
            .map_or_else(PlatformTravel::default, Platform::travel)
    }

    fn poll_due(&self, now_ns: u64) -> bool {
        let every_ns = if self.failed_polls >= SILENT_AFTER {
            SILENT_PLATFORM_PERIOD_NS
        } else {
            PLATFORM_PERIOD_NS
        };
        self.last_poll_ns
            .is_none_or(|last| now_ns.saturating_sub(last) >= every_ns)
    }
}

impl<P: Platform, T: Tractor> Devices for ExecutiveDevices<P, T> {
    type Readings = ExecutiveReadings;
    type Commands = ExecutiveCommands;
    type Error = AnyDeviceError;

    fn stop(&mut self) -> Result<(), AnyDeviceError> {
        if self.stopped {
            return Ok(());
        }
        let platform = self.platform.as_mut().map_or(Ok(()), Platform::stop);
        let tractor = self.tractor.as_mut().map_or(Ok(()), Tractor::stop);
        platform.map_err(AnyDeviceError::new)?;
        tractor.map_err(AnyDeviceError::new)?;
        self.stopped = true;
        Ok(())
    }

    /// Nothing: the stages and the trailer keep their targets (the executive's faults are
    /// the platform's own, reported).
    fn hold(&mut self) -> Result<(), AnyDeviceError> {
        Ok(())
    }

    fn read(&mut self, now_ns: u64) -> Result<Option<ExecutiveReadings>, AnyDeviceError> {
        let tractor = match self.tractor.as_mut().map(Tractor::position) {
            Some(Ok(position)) => Some((position.position_m, position.in_motion)),
            Some(Err(error)) => {
                tracing::debug!(%error, "tractor position");
                None
            }
            None => None,
        };
        let due = self.poll_due(now_ns);
        if let Some(platform) = self.platform.as_mut()
            && due
        {
            self.last_poll_ns = Some(now_ns);
            match platform.position() {
                Ok(position) => {
                    self.failed_polls = 0;
                    let travel = platform.travel();
                    self.platform_view = Some(PlatformView {
                        position_m: [position.in_out_m, position.up_down_m],
                        in_motion: position.in_motion,
                        travel_max_m: [travel.in_out_max_m, travel.up_down_max_m],
                    });
                }
                Err(error) => {
                    self.failed_polls = self.failed_polls.saturating_add(1);
                    if self.failed_polls == SILENT_AFTER {
                        tracing::warn!(%error, "platform silent: polling at 1 Hz");
                    }
                    self.platform_view = None;
                    return Err(AnyDeviceError::new(error));
                }
            }
        }
        Ok(Some(ExecutiveReadings {
            platform: self.platform_view,
            tractor,
            tractor_past_end: std::mem::take(&mut self.tractor_past_end),
        }))
    }

    fn write(&mut self, commands: &ExecutiveCommands) -> Result<(), AnyDeviceError> {
        self.stopped = false;
        if let (Some((mode, arms)), Some(store)) = (commands.save_mode, &self.mode_store)
            && let Err(error) = save_mode(&store.path, &store.token, mode, arms)
        {
            tracing::warn!(%error, path = %store.path.display(), "mode file not written");
        }
        if let (Some(distance_m), Some(tractor)) =
            (commands.tractor_advance_m, self.tractor.as_mut())
        {
            match tractor.advance(distance_m) {
                Ok(()) => {}
                // Past the end of the row (the trait's `InvalidRequest`): a row resumed part
                // way (the simulated world keeps its state) has fewer stops left.
                Err(error) if error.kind() == ErrorKind::InvalidRequest => {
                    tracing::info!(%error, distance_m, "tractor advance refused: the row ends here");
                    self.tractor_past_end = true;
                }
                // Not reached (link down, no feedback): the cycle sends it again while the
                // trailer is not at the stop.
                Err(error) => {
                    tracing::warn!(%error, distance_m, "tractor advance not sent: retried");
                }
            }
        }
        let (Some(order), Some(platform)) = (commands.platform, self.platform.as_mut()) else {
            return Ok(());
        };
        let result = match order {
            PlatformOrder::MoveTo { target_m } => {
                let result = platform.move_to(target_m[0], target_m[1]);
                if result.is_ok() {
                    // Poll at once: the stop cycle waits for the move to end.
                    self.last_poll_ns = None;
                    self.platform_view = None;
                }
                result
            }
            PlatformOrder::Stop => platform.stop(),
        };
        result.map_err(|error| {
            tracing::warn!(%error, ?order, "platform command refused");
            AnyDeviceError::new(error)
        })
    }
}
