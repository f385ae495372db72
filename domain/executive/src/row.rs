//! The executive's part of the field workflow ([`RowWork`]): it drives
//! [`harvest_field::StopCycle`] along a row.
//!
//! Why in the executive and not in a node of its own: the executive is already the one writer
//! of the platform commands and the holder of the operator's mode; a separate field node would
//! be a second platform writer (two drivers racing on the stages) and would have to mirror the
//! mode to stop positioning on a pause or an e-stop. So the cycle ticks only while the mode is
//! harvesting, and its platform moves go through the same device as the operator's.
//!
//! Per tick: the newest detection set (its laser-refined apples are counted per stop), the
//! arms' states, the platform's and the tractor's positions and the new `harvest/events`
//! (assignments, ended attempts, the vacuum supervisor's "harvest complete") feed the cycle;
//! its actions become the platform target, the tractor advance, and the `StopFinished` /
//! `RowFinished` events (the lines `harvest up` prints).

use harvest_field::{
    FieldAction, FieldView, NextStopRefusal, RowReport, StageTravel, StopCycle, StopCycleConfig,
    StopCycleError, StopReport,
};
use harvest_ipc::FixedString;
use harvest_ipc::payloads::{
    AppleDetections, ArmPhase, ArmState, HarvestCause, HarvestEvent, HarvestEventKind,
    HarvestEventSource, LocalizationMethod,
};
use harvest_robot_model::params::ArmParams;

/// The row the executive works.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RowOptions {
    pub stops: u32,
    pub stop_spacing_m: f64,
    /// Advance to the next stop once a stop is harvested (else the operator's "next stop").
    pub auto_advance: bool,
    /// A stop is harvested once nothing was assigned or attempted this long after fresh
    /// detections, ns.
    pub quiet_ns: u64,
}

/// A platform move or tractor advance not done after this long is sent again, ns.
pub const RESEND_NS: u64 = 10_000_000_000;

/// What the row asks of the devices and the channels this tick.
#[derive(Debug, Default)]
pub struct RowEffects {
    pub platform_target_m: Option<[f64; 2]>,
    pub tractor_advance_m: Option<f64>,
    pub events: Vec<HarvestEvent>,
}

/// The stop cycle and what it was told (module documentation).
#[derive(Debug)]
pub struct RowWork {
    cycle: StopCycle,
    detections: Option<(u64, Vec<[f64; 3]>)>,
    row_report: Option<RowReport>,
}

/// What the cycle sees of the stack besides its own inputs.
#[derive(Debug, Clone, Copy)]
pub struct RowStack<'a> {
    pub arm_states: [Option<&'a ArmState>; 2],
    pub platform: Option<([f64; 2], bool)>,
    pub tractor: Option<(f64, bool)>,
}

impl RowWork {
    pub fn new(options: RowOptions, travel_max_m: [f64; 2]) -> Result<Self, StopCycleError> {
        let config = StopCycleConfig {
            stops: options.stops,
            stop_spacing_m: options.stop_spacing_m,
            auto_advance: options.auto_advance,
            travel: StageTravel {
                in_out_max_m: travel_max_m[0],
                up_down_max_m: travel_max_m[1],
            },
            quiet_ns: options.quiet_ns,
            resend_ns: RESEND_NS,
        };
        Ok(Self {
            cycle: StopCycle::new(config, [ArmParams::arm1(), ArmParams::arm2()])?,
            detections: None,
            row_report: None,
        })
    }

    /// The stop cycle (its phase, its finished stops).
    pub fn cycle(&self) -> &StopCycle {
        &self.cycle
    }

    /// The row's report once it is done.
    pub fn row_report(&self) -> Option<&RowReport> {
        self.row_report.as_ref()
    }

    pub fn done(&self) -> bool {
        self.row_report.is_some()
    }

    /// True while the stop cycle holds new approaches (see [`StopCycle::holds_approaches`]).
    pub fn holds_approaches(&self) -> bool {
        !self.done() && self.cycle.holds_approaches()
    }

    /// A fresh detection set (every tick one arrives, whatever the mode).
    pub fn on_detections(&mut self, set: &AppleDetections) {
        let apples = set.apples.iter().map(|a| a.position_in_robot_m).collect();
        self.detections = Some((set.source_capture_ns, apples));
        for apple in set.apples.iter() {
            if apple.method == LocalizationMethod::LaserScan {
                self.cycle.on_laser_refined(apple.apple_id);
            }
        }
    }

    /// A harvest event of another node (ended attempts count for the stop they ended in, also
    /// when "next stop" comes between two ticks).
    pub fn on_event(&mut self, event: &HarvestEvent) {
        if event.source == HarvestEventSource::Field {
            return;
        }
        let stamp_ns = event.header.capture_ns;
        match event.kind.get() {
            Ok(HarvestEventKind::Assigned) => self.cycle.on_assigned(stamp_ns),
            Ok(HarvestEventKind::AttemptEnded) => {
                let cause = event.cause.get().unwrap_or(HarvestCause::Other);
                self.cycle
                    .on_attempt_ended(stamp_ns, event.harvested != 0, cause.label());
            }
            Ok(HarvestEventKind::HarvestComplete) => self.cycle.on_harvest_complete(stamp_ns),
            _ => {}
        }
    }

    /// The last tractor advance was refused as past the end of the row.
    pub fn on_row_end(&mut self, now_ns: u64, effects: &mut RowEffects) {
        if !self.done() {
            let actions = self.cycle.row_ends_here(now_ns);
            self.carry_out(now_ns, actions, effects);
        }
    }

    /// One tick; `harvesting`: the operator's mode lets the robot work.
    pub fn tick(
        &mut self,
        now_ns: u64,
        harvesting: bool,
        stack: &RowStack<'_>,
        effects: &mut RowEffects,
    ) {
        if self.done() || !harvesting {
            return;
        }
        let view = self.view(stack);
        let actions = self.cycle.tick(now_ns, &view);
        self.carry_out(now_ns, actions, effects);
    }

    /// The operator's "next stop" ([`StopCycle::next_stop`]): the stop's figures are
    /// published, the trailer advances. `Ok` says what was done, `Err` is the cycle's refusal,
    /// in words.
    pub fn next_stop(
        &mut self,
        now_ns: u64,
        stack: &RowStack<'_>,
        effects: &mut RowEffects,
    ) -> Result<String, String> {
        if self.done() {
            return Err(NextStopRefusal::RowDone.to_string());
        }
        let view = self.view(stack);
        let stop = self.cycle.stop_number();
        let actions = self
            .cycle
            .next_stop(now_ns, &view)
            .map_err(|refusal| refusal.to_string())?;
        self.carry_out(now_ns, actions, effects);
        Ok(if self.done() {
            format!("stop {stop} ended: the row is done")
        } else {
            format!("stop {stop} ended: advancing to stop {}", stop + 1)
        })
    }

    fn view(&self, stack: &RowStack<'_>) -> FieldView {
        let parked = |state: &Option<&ArmState>| {
            state.is_some_and(|s| s.phase == ArmPhase::Idle && s.holding == 0)
        };
        FieldView {
            tractor: stack.tractor,
            platform: stack.platform,
            arms_parked: stack.arm_states.iter().all(parked),
            arms_holding: stack.arm_states.iter().flatten().any(|s| s.holding != 0),
            detections: self.detections.clone(),
        }
    }

    fn carry_out(&mut self, now_ns: u64, actions: Vec<FieldAction>, effects: &mut RowEffects) {
        for action in actions {
            match action {
                FieldAction::MovePlatform { target_m } => {
                    effects.platform_target_m = Some(target_m)
                }
                FieldAction::AdvanceTractor { distance_m } => {
                    effects.tractor_advance_m = Some(distance_m)
                }
                FieldAction::StopFinished(report) => {
                    let line = stop_line(&report);
                    tracing::info!(%line, "stop finished");
                    effects.events.push(field_event(
                        now_ns,
                        HarvestEventKind::StopFinished,
                        report.trailer_m,
                        &line,
                    ));
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
                    effects.events.push(field_event(
                        now_ns,
                        HarvestEventKind::RowFinished,
                        trailer_m,
                        &line,
                    ));
                    self.row_report = Some(row);
                }
            }
        }
    }
}

fn field_event(now_ns: u64, kind: HarvestEventKind, trailer_m: f64, line: &str) -> HarvestEvent {
    let mut event = HarvestEvent::new(now_ns, HarvestEventSource::Field, kind, 0, 0);
    event.position_in_robot_m = [trailer_m, f64::NAN, f64::NAN];
    event.reason = FixedString::new(line);
    event
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
