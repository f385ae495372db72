//! The run's observations as [`TraceEvent`]s for the independent [`SafetyMonitor`]: valve
//! commands and the pressure inference's conclusions (from the vacuum node's events), phase
//! changes (from the arm nodes), every joint set-point sent to the servos with the Table 1
//! limits, and both end-effector positions measured by the simulator (eq. 1 of the encoders),
//! all stamped with the tick's time.

use harvest_arm::node::{ArmNodeEvent, ServoOrder};
use harvest_robot_model::ArmId;
use harvest_robot_model::coordination_phase::CoordinationPhase;
use harvest_robot_model::params::ArmParams;
use harvest_safety::safety_monitor::{MonitorConfig, SafetyMonitor, TraceError, Violation};
use harvest_safety::trace::{JointId, TraceEvent};
use harvest_vacuum::node::VacuumNodeEvent;

const JOINTS: [JointId; 4] = [
    JointId::Extension,
    JointId::Pitch,
    JointId::Yaw,
    JointId::Twist,
];

/// Feeds one episode's observations to a [`SafetyMonitor`].
#[derive(Debug, Clone)]
pub struct SafetyTrace {
    monitor: SafetyMonitor,
    limits: [([f64; 4], [f64; 4]); 2],
    events: u64,
}

impl Default for SafetyTrace {
    fn default() -> Self {
        Self::new(MonitorConfig::default())
    }
}

impl SafetyTrace {
    /// A trace judged with `config`.
    pub fn new(config: MonitorConfig) -> Self {
        let limits = [ArmParams::arm1(), ArmParams::arm2()].map(|p| {
            (
                p.position_limits.min.to_array(),
                p.position_limits.max.to_array(),
            )
        });
        Self {
            monitor: SafetyMonitor::new(config),
            limits,
            events: 0,
        }
    }

    /// Events observed so far.
    pub fn event_count(&self) -> u64 {
        self.events
    }

    /// Violations found so far.
    pub fn violations(&self) -> &[Violation] {
        self.monitor.violations()
    }

    fn observe(&mut self, event: TraceEvent) -> Result<(), TraceError> {
        self.events += 1;
        self.monitor.observe(&event)
    }

    /// The vacuum node's valve and inference events of a tick, in their order.
    pub fn vacuum_events(
        &mut self,
        stamp_ns: u64,
        events: &[VacuumNodeEvent],
    ) -> Result<(), TraceError> {
        for event in events {
            match event {
                VacuumNodeEvent::ValveOpened { arm } => {
                    self.observe(TraceEvent::ValveOpened {
                        stamp_ns,
                        arm: *arm,
                    })?;
                }
                VacuumNodeEvent::ValveClosed { arm, .. } => {
                    self.observe(TraceEvent::ValveClosed {
                        stamp_ns,
                        arm: *arm,
                    })?;
                }
                VacuumNodeEvent::Attachment(change) => {
                    if change.from.is_sealed() != change.to.is_sealed() {
                        self.observe(TraceEvent::AttachmentChanged {
                            stamp_ns,
                            arm: change.arm,
                            sealed: change.to.is_sealed(),
                        })?;
                    }
                    if let Some(kind) = change.failure() {
                        self.observe(TraceEvent::FailureDetected {
                            stamp_ns,
                            arm: change.arm,
                            kind,
                        })?;
                    }
                }
                _ => {}
            }
        }
        Ok(())
    }

    /// An arm node's phase changes of a tick.
    pub fn arm_events(
        &mut self,
        stamp_ns: u64,
        arm: ArmId,
        events: &[ArmNodeEvent],
    ) -> Result<(), TraceError> {
        for event in events {
            if let ArmNodeEvent::PhaseChanged { to, .. } = event {
                self.observe(TraceEvent::PhaseChanged {
                    stamp_ns,
                    arm,
                    phase: CoordinationPhase::from_reported(*to),
                })?;
            }
        }
        Ok(())
    }

    /// The set-points sent to `arm`'s servos this tick (nothing for a brake).
    pub fn servo_order(
        &mut self,
        stamp_ns: u64,
        arm: ArmId,
        order: &ServoOrder,
    ) -> Result<(), TraceError> {
        let ServoOrder::Track { position, .. } = order else {
            return Ok(());
        };
        let (lower, upper) = self.limits[arm.index()];
        for j in 0..4 {
            self.observe(TraceEvent::JointCommand {
                stamp_ns,
                arm,
                joint: JOINTS[j],
                command: position[j],
                lower: lower[j],
                upper: upper[j],
            })?;
        }
        Ok(())
    }

    /// The emergency stop was engaged (or released) at `stamp_ns`.
    pub fn emergency_stop(&mut self, stamp_ns: u64, engaged: bool) -> Result<(), TraceError> {
        self.observe(TraceEvent::EmergencyStop { stamp_ns, engaged })
    }

    /// Both measured end-effector positions, robot frame, m.
    pub fn end_effectors(
        &mut self,
        stamp_ns: u64,
        in_robot_m: [[f64; 3]; 2],
    ) -> Result<(), TraceError> {
        self.observe(TraceEvent::EndEffectors {
            stamp_ns,
            arm1_in_robot_m: in_robot_m[0],
            arm2_in_robot_m: in_robot_m[1],
        })
    }

    /// Ends the trace at `end_ns` and returns every violation.
    pub fn finish(mut self, end_ns: u64) -> Vec<Violation> {
        self.monitor.finish(end_ns).to_vec()
    }
}
