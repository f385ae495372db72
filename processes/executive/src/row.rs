//! The executive's part of the field workflow: it drives [`harvest_field::StopCycle`] along a
//! row.
//!
//! Why here and not in a process of its own: the executive is already the one writer of the
//! platform commands and the holder of the operator's mode; a separate `harvest field` process
//! would be a second platform writer (two drivers racing on `hw/platform/command`) and would
//! have to mirror the mode to stop positioning on a pause or an e-stop. So the cycle ticks only
//! while the mode is harvesting, and its platform moves go through the same driver as the
//! operator's.
//!
//! Per tick: the newest detection set (`perception/apples`; its laser-refined apples are
//! counted per stop), the arms' states, the platform's
//! and the tractor's positions and the new `harvest/events` (assignments, ended attempts, the
//! vacuum supervisor's "harvest complete") feed the cycle; its actions move the platform,
//! advance the tractor, and publish `StopFinished` / `RowFinished` events on `harvest/events`
//! (the lines `harvest up` prints).

use harvest_field::{
    FieldAction, FieldView, NextStopRefusal, StageTravel, StopCycle, StopCycleConfig, StopReport,
};
use harvest_hw::tractor::Tractor;
use harvest_hw::tractor::sim::SimTractor;
use harvest_hw::{AnyDeviceError, DeviceError, ErrorKind};
use harvest_ipc::catalogue::{HARVEST_EVENTS, PERCEPTION_APPLES};
use harvest_ipc::payloads::{
    AppleDetections, ArmPhase, ArmState, HarvestCause, HarvestEvent, HarvestEventKind,
    HarvestEventSource, LocalizationMethod,
};
use harvest_ipc::{Context, FixedString, Publisher, Subscriber};
use harvest_robot_model::params::ArmParams;
use std::collections::VecDeque;
use std::time::Duration;

use crate::process::ExecutiveProcessError;

/// The row the executive works, from its command line.
#[derive(Debug, Clone, Copy)]
pub struct RowOptions {
    pub stops: u32,
    pub stop_spacing_m: f64,
    pub auto_advance: bool,
    pub quiet_ms: u64,
}

/// A platform move or tractor advance not done after this long is sent again, ns.
const RESEND_NS: u64 = 10_000_000_000;

/// How long the tractor driver waits for its first feedback.
const TRACTOR_TIMEOUT: Duration = Duration::from_secs(5);

/// The answer of the row to "next stop": what was done and the platform target to move to (if
/// any), or the stop cycle's refusal in words.
pub type NextStopOutcome = Result<(String, Option<[f64; 2]>), String>;

/// The stop cycle with its ports and the tractor.
pub struct RowLink {
    cycle: StopCycle,
    tractor: SimTractor,
    apples_in: Subscriber<AppleDetections>,
    events_in: Subscriber<HarvestEvent>,
    events_out: Publisher<HarvestEvent>,
    detections: Option<(u64, Vec<[f64; 3]>)>,
    done: bool,
}

impl RowLink {
    pub fn connect(
        context: &Context,
        options: RowOptions,
        travel_max_m: [f64; 2],
    ) -> Result<Self, ExecutiveProcessError> {
        let config = StopCycleConfig {
            stops: options.stops,
            stop_spacing_m: options.stop_spacing_m,
            auto_advance: options.auto_advance,
            travel: StageTravel {
                in_out_max_m: travel_max_m[0],
                up_down_max_m: travel_max_m[1],
            },
            quiet_ns: options.quiet_ms * 1_000_000,
            resend_ns: RESEND_NS,
        };
        let cycle = StopCycle::new(config, [ArmParams::arm1(), ArmParams::arm2()])?;
        let tractor = SimTractor::connect(context, TRACTOR_TIMEOUT)
            .map_err(|error| ExecutiveProcessError::Tractor(AnyDeviceError::new(error)))?;
        Ok(Self {
            cycle,
            tractor,
            apples_in: context.subscriber(PERCEPTION_APPLES)?,
            events_in: context.subscriber_with_buffer(HARVEST_EVENTS, 256)?,
            events_out: context.publisher(HARVEST_EVENTS)?,
            detections: None,
            done: false,
        })
    }

    /// True while the stop cycle holds new approaches (see [`StopCycle::holds_approaches`]).
    pub fn holds_approaches(&self) -> bool {
        !self.done && self.cycle.holds_approaches()
    }

    /// One tick. `harvesting`: the operator's mode lets the robot work; `platform`: the stages'
    /// position and motion. Returns the platform target to move to, if any.
    pub fn tick(
        &mut self,
        now_ns: u64,
        harvesting: bool,
        arm_states: &[Option<ArmState>; 2],
        platform: Option<([f64; 2], bool)>,
    ) -> Result<Option<[f64; 2]>, ExecutiveProcessError> {
        self.take_inputs()?;
        if self.done || !harvesting {
            return Ok(None);
        }
        let view = self.view(arm_states, platform);
        let actions = self.cycle.tick(now_ns, &view);
        self.carry_out(now_ns, actions)
    }

    /// The newest detections and the new harvest events (ended attempts count for the stop
    /// they ended in, also when "next stop" comes between two ticks).
    fn take_inputs(&mut self) -> Result<(), ExecutiveProcessError> {
        if let Some(sample) = self.apples_in.receive_latest()? {
            let apples = sample
                .apples
                .iter()
                .map(|apple| apple.position_in_robot_m)
                .collect();
            self.detections = Some((sample.source_capture_ns, apples));
            for apple in sample.apples.iter() {
                if apple.method == LocalizationMethod::LaserScan {
                    self.cycle.on_laser_refined(apple.apple_id);
                }
            }
        }
        let cycle = &mut self.cycle;
        self.events_in.drain(|event| {
            if event.source == HarvestEventSource::Field {
                return;
            }
            let stamp_ns = event.header.capture_ns;
            match event.kind.get() {
                Ok(HarvestEventKind::Assigned) => cycle.on_assigned(stamp_ns),
                Ok(HarvestEventKind::AttemptEnded) => {
                    let cause = event.cause.get().unwrap_or(HarvestCause::Other);
                    cycle.on_attempt_ended(stamp_ns, event.harvested != 0, cause.label());
                }
                Ok(HarvestEventKind::HarvestComplete) => cycle.on_harvest_complete(stamp_ns),
                _ => {}
            }
        })?;
        Ok(())
    }

    /// The operator's "next stop" ([`StopCycle::next_stop`]): the stop's figures are published,
    /// the trailer advances. `Err` is the cycle's refusal, in words; `Ok` says what was done
    /// and the platform target to move to, if any.
    pub fn next_stop(
        &mut self,
        now_ns: u64,
        arm_states: &[Option<ArmState>; 2],
        platform: Option<([f64; 2], bool)>,
    ) -> Result<NextStopOutcome, ExecutiveProcessError> {
        self.take_inputs()?;
        if self.done {
            return Ok(Err(NextStopRefusal::RowDone.to_string()));
        }
        let view = self.view(arm_states, platform);
        let stop = self.cycle.stop_number();
        match self.cycle.next_stop(now_ns, &view) {
            Ok(actions) => {
                let target = self.carry_out(now_ns, actions)?;
                let what = if self.done {
                    format!("stop {stop} ended: the row is done")
                } else {
                    format!("stop {stop} ended: advancing to stop {}", stop + 1)
                };
                Ok(Ok((what, target)))
            }
            Err(refusal) => Ok(Err(refusal.to_string())),
        }
    }

    /// What the stop cycle sees now.
    fn view(
        &mut self,
        arm_states: &[Option<ArmState>; 2],
        platform: Option<([f64; 2], bool)>,
    ) -> FieldView {
        let tractor = match self.tractor.position() {
            Ok(position) => Some((position.position_m, position.in_motion)),
            Err(error) => {
                tracing::debug!(%error, "tractor position");
                None
            }
        };
        let parked = |state: &Option<ArmState>| {
            state.is_some_and(|s| s.phase == ArmPhase::Idle && s.holding == 0)
        };
        FieldView {
            tractor,
            platform,
            arms_parked: arm_states.iter().all(parked),
            arms_holding: arm_states.iter().flatten().any(|s| s.holding != 0),
            detections: self.detections.clone(),
        }
    }

    /// Carries out the stop cycle's actions; returns the platform target to move to, if any.
    fn carry_out(
        &mut self,
        now_ns: u64,
        actions: Vec<FieldAction>,
    ) -> Result<Option<[f64; 2]>, ExecutiveProcessError> {
        let mut platform_target = None;
        let mut actions = VecDeque::from(actions);
        while let Some(action) = actions.pop_front() {
            match action {
                FieldAction::MovePlatform { target_m } => platform_target = Some(target_m),
                FieldAction::AdvanceTractor { distance_m } => {
                    match self.tractor.advance(distance_m) {
                        Ok(()) => {}
                        // Past the end of the row (the trait's `InvalidRequest`): a row resumed
                        // part way (the simulated world keeps its state) has fewer stops left.
                        Err(error) if error.kind() == ErrorKind::InvalidRequest => {
                            tracing::info!(%error, distance_m, "tractor advance refused: the row ends here");
                            actions.extend(self.cycle.row_ends_here(now_ns));
                        }
                        // Not reached (link down, no feedback): the cycle sends it again while the
                        // trailer is not at the stop.
                        Err(error) => {
                            tracing::warn!(%error, distance_m, "tractor advance not sent: retried");
                        }
                    }
                }
                FieldAction::StopFinished(report) => {
                    let line = stop_line(&report);
                    tracing::info!(%line, "stop finished");
                    self.publish(
                        now_ns,
                        HarvestEventKind::StopFinished,
                        report.trailer_m,
                        &line,
                    )?;
                }
                FieldAction::RowFinished(row) => {
                    let line = format!(
                        "{} stops, detected {}, reachable {}, out of reach {}, attempted {}, \
                         harvested {}, {:.1} s",
                        row.stops.len(),
                        row.detected(),
                        row.reachable(),
                        row.out_of_reach(),
                        row.attempted(),
                        row.harvested(),
                        row.duration_ns as f64 * 1e-9
                    );
                    tracing::info!(%line, failures = ?row.failures(), "row finished");
                    let trailer_m = row.stops.last().map_or(0.0, |s| s.trailer_m);
                    self.publish(now_ns, HarvestEventKind::RowFinished, trailer_m, &line)?;
                    self.done = true;
                }
            }
        }
        Ok(platform_target)
    }

    fn publish(
        &mut self,
        now_ns: u64,
        kind: HarvestEventKind,
        trailer_m: f64,
        line: &str,
    ) -> Result<(), ExecutiveProcessError> {
        let mut event = HarvestEvent::new(now_ns, HarvestEventSource::Field, kind, 0, 0);
        event.position_in_robot_m = [trailer_m, f64::NAN, f64::NAN];
        event.reason = FixedString::new(line);
        self.events_out.publish(&event)?;
        Ok(())
    }
}

/// One stop as `harvest up` prints it (fits a harvest event's reason; the failures by cause,
/// which would not, are added by the harvest log from the attempts it saw end during the stop).
fn stop_line(report: &StopReport) -> String {
    format!(
        "stop {} @{:.2} m: platform ({:.2}, {:.2}) m, reach {}->{} of {}, out {}, laser {}, att {}, \
         ok {}",
        report.stop,
        report.trailer_m,
        report.offset_m[0],
        report.offset_m[1],
        report.reachable_before,
        report.reachable_after,
        report.detected,
        report.out_of_reach,
        report.laser_refined,
        report.attempted,
        report.harvested
    )
}
