//! The mapping ([`crate::mapping`]) and the independent checker
//! ([`harvest_vacuum::safety_monitor::SafetyMonitor`]) fed message by message, with counts.

use std::fmt::Write as _;

use harvest_ipc::payloads::{ArmCommand, ArmState, EmergencyStop, VacuumState};
use harvest_vacuum::ArmId;
use harvest_vacuum::safety_monitor::{MonitorConfig, SafetyMonitor, TraceError, Violation};
use harvest_vacuum::trace::TraceEvent;

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
}

impl StackMonitor {
    /// A monitor with the given mapping and reaction settings.
    pub fn new(mapping: MappingConfig, checks: MonitorConfig) -> Self {
        Self {
            mapper: StackTraceMapper::new(mapping),
            monitor: SafetyMonitor::new(checks),
            events: Vec::with_capacity(8),
            report: MonitorReport::default(),
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
