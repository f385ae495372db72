//! The mapping ([`crate::mapping`]) and the independent checker
//! ([`harvest_safety::safety_monitor::SafetyMonitor`]) fed message by message, with counts.

use std::fmt::Write as _;

use harvest_ipc::payloads::{
    ArmCommand, ArmPhase as PhaseCode, ArmState, EmergencyStop, VacuumState,
};
use harvest_robot_model::ArmId;
use harvest_safety::safety_monitor::{MonitorConfig, SafetyMonitor, TraceError, Violation};
use harvest_safety::trace::TraceEvent;

use crate::mapping::{MappingConfig, StackTraceMapper};

/// One message of a monitored channel.
#[derive(Debug, Clone, Copy)]
pub enum StackMessage<'a> {
    /// `vacuum/state`.
    Vacuum(&'a VacuumState),
    /// `arm{n}/command` of an arm.
    Command(ArmId, &'a ArmCommand),
    /// `arm{n}/state` of an arm.
    State(ArmId, &'a ArmState),
    /// `safety/emergency_stop`.
    Stop(&'a EmergencyStop),
}

/// The stack's reaction to one engagement of the emergency stop, as seen on the channels: from
/// the `safety/emergency_stop` message to the first `vacuum/state` reporting all four valves
/// closed at their end stops, and to both arms publishing the `Stopped` phase (drives braked).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StopReaction {
    /// When the engaged stop was received, ns.
    pub engaged_ns: u64,
    /// Delay until every valve was reported closed and settled, s.
    pub valves_closed_s: Option<f64>,
    /// Delay until both arms reported `Stopped`, s.
    pub arms_holding_s: Option<f64>,
}

/// What a monitoring run found.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct MonitorReport {
    /// Messages judged.
    pub messages: u64,
    /// Trace events they became.
    pub trace_events: u64,
    /// Messages skipped: another schema than the catalogue's, or undecodable.
    pub skipped_messages: u64,
    /// First and last receive time, ns.
    pub span_ns: Option<(u64, u64)>,
    /// Every violation, in the order found.
    pub violations: Vec<Violation>,
    /// Each engagement of the emergency stop and how fast the stack reacted.
    pub emergency_stops: Vec<StopReaction>,
}

impl MonitorReport {
    /// The final summary printed by `harvest monitor` (the violations themselves are printed
    /// as they are found).
    pub fn render(&self) -> String {
        let mut out = String::new();
        let span_s = self
            .span_ns
            .map_or(0.0, |(a, b)| b.saturating_sub(a) as f64 * 1e-9);
        let _ = writeln!(
            out,
            "monitor: {} messages over {span_s:.2} s -> {} trace events ({} skipped); {} \
             violation(s)",
            self.messages,
            self.trace_events,
            self.skipped_messages,
            self.violations.len()
        );
        for stop in &self.emergency_stops {
            let delay = |d: Option<f64>| {
                d.map_or_else(|| "not seen".to_owned(), |d| format!("{:.1} ms", d * 1e3))
            };
            let _ = writeln!(
                out,
                "  emergency stop {:.3} s into the run: all valves closed after {}, both arms \
                 holding after {}",
                stop.engaged_ns
                    .saturating_sub(self.span_ns.map_or(0, |(first, _)| first))
                    as f64
                    * 1e-9,
                delay(stop.valves_closed_s),
                delay(stop.arms_holding_s)
            );
        }
        out
    }
}

/// Mapping + checker.
#[derive(Debug, Clone)]
pub struct StackMonitor {
    mapper: StackTraceMapper,
    monitor: SafetyMonitor,
    events: Vec<TraceEvent>,
    report: MonitorReport,
    stop_engaged: bool,
    arm_stopped: [bool; 2],
}

impl StackMonitor {
    /// A monitor with the given mapping and reaction settings.
    pub fn new(mapping: MappingConfig, checks: MonitorConfig) -> Self {
        Self {
            mapper: StackTraceMapper::new(mapping),
            monitor: SafetyMonitor::new(checks),
            events: Vec::with_capacity(8),
            report: MonitorReport::default(),
            stop_engaged: false,
            arm_stopped: [false; 2],
        }
    }

    /// Judges one message received at `receive_ns`; returns the violations it revealed.
    pub fn feed(
        &mut self,
        receive_ns: u64,
        message: StackMessage<'_>,
    ) -> Result<&[Violation], TraceError> {
        self.events.clear();
        match message {
            StackMessage::Vacuum(state) => {
                self.mapper
                    .vacuum_state(receive_ns, state, &mut self.events)
            }
            StackMessage::Command(arm, command) => {
                self.mapper
                    .arm_command(receive_ns, arm, command, &mut self.events)
            }
            StackMessage::State(arm, state) => {
                self.mapper
                    .arm_state(receive_ns, arm, state, &mut self.events)
            }
            StackMessage::Stop(stop) => {
                self.mapper
                    .emergency_stop(receive_ns, stop, &mut self.events)
            }
        }
        self.time_stop(receive_ns, message);
        let before = self.monitor.violations().len();
        for event in &self.events {
            self.monitor.observe(event)?;
        }
        self.report.messages += 1;
        self.report.trace_events += self.events.len() as u64;
        self.report.span_ns = Some(match self.report.span_ns {
            Some((first, last)) => (first, last.max(receive_ns)),
            None => (receive_ns, receive_ns),
        });
        Ok(&self.monitor.violations()[before..])
    }

    /// Measures the reaction to the emergency stop ([`StopReaction`]).
    fn time_stop(&mut self, receive_ns: u64, message: StackMessage<'_>) {
        match message {
            StackMessage::Stop(stop) => {
                let engaged = stop.engaged != 0;
                if engaged && !self.stop_engaged {
                    self.report.emergency_stops.push(StopReaction {
                        engaged_ns: receive_ns,
                        ..StopReaction::default()
                    });
                }
                self.stop_engaged = engaged;
            }
            StackMessage::State(arm, state) => {
                self.arm_stopped[arm.index()] = state.phase == PhaseCode::Stopped;
            }
            StackMessage::Vacuum(_) | StackMessage::Command(..) => {}
        }
        if !self.stop_engaged {
            return;
        }
        let arms_holding = self.arm_stopped == [true, true];
        let Some(reaction) = self.report.emergency_stops.last_mut() else {
            return;
        };
        let delay_s = receive_ns.saturating_sub(reaction.engaged_ns) as f64 * 1e-9;
        if let StackMessage::Vacuum(v) = message
            && reaction.valves_closed_s.is_none()
            && v.valve_open == [0; 4]
            && v.valve_in_transit == [0; 4]
        {
            reaction.valves_closed_s = Some(delay_s);
        }
        if arms_holding && reaction.arms_holding_s.is_none() {
            reaction.arms_holding_s = Some(delay_s);
        }
    }

    /// Counts a message that could not be judged.
    pub fn skip(&mut self) {
        self.report.skipped_messages += 1;
    }

    /// Ends the run at `end_ns` (deadlines still running are judged) and returns the report.
    pub fn finish(mut self, end_ns: u64) -> MonitorReport {
        self.report.violations = self.monitor.finish(end_ns).to_vec();
        self.report
    }

    /// Violations so far.
    pub fn violations(&self) -> &[Violation] {
        self.monitor.violations()
    }
}
