//! Stack channels -> [`TraceEvent`]s: the one place where what the stack publishes is read as
//! safety observations.
//!
//! | channel | trace events |
//! |---|---|
//! | `vacuum/state` | `ValveOpened` / `ValveClosed` when arm `i`'s inlet gate (valve `2i+1`) is reported commanded open / closed; `AttachmentChanged` when `arm_attachment` enters or leaves "sealed" with the gate open; `FailureDetected(Dropped)` when a seal is lost with the gate still open; `FailureDetected(AttachFailed)` when the gate has been open and settled (inlet at its end stop, vent shut) for the attach window without a seal |
//! | `arm{1,2}/command` | four `JointCommand`s per set-point message (D, theta, phi, twist) with the arm's Table 1 limits; nothing for a brake (`hold = 1`) |
//! | `arm{1,2}/state` | `PhaseChanged` on a new phase; `EndEffectors` with both arms' reported end-effector positions once both are known |
//! | `safety/emergency_stop` | `EmergencyStop` when `engaged` changes |
//!
//! Times: every event carries the time the monitor received the message (the live monitor's
//! monotonic clock, a recording's `log_time`), made non-decreasing, so events from several
//! channels form one ordered trace. The reaction deadlines are therefore judged as an observer
//! of the channels sees them: one control period of the vacuum node plus the period in which
//! the board reports the gate's new position (see [`STACK_REACTION_NS`]).
//!
//! The attach-failure inference is the monitor's own rule, not the vacuum node's estimator: the
//! state channel shows "open, no seal" for both an attempt in progress and a failed one, so the
//! monitor declares a failure once that has lasted longer than the window the supervisor is
//! configured with ([`DEFAULT_ATTACH_WINDOW_NS`]), and then requires the valve to close within
//! the reaction deadline.

use harvest_ipc::WireCode;
use harvest_ipc::payloads::{
    ArmAttachment, ArmCommand, ArmPhase as PhaseCode, ArmState, EmergencyStop, VacuumState,
};
use harvest_robot_model::ArmId;
use harvest_robot_model::coordination_phase::CoordinationPhase;
use harvest_robot_model::params::ArmParams;
use harvest_safety::trace::{FailureKind, JointId, TraceEvent};

/// The vacuum supervisor's attach timeout with the simulated valve box (500 ms,
/// `harvest_vacuum::process::SIM_ATTACH_TIMEOUT_NS`) plus two control periods for the report to
/// reach the channel, ns.
pub const DEFAULT_ATTACH_WINDOW_NS: u64 = 510_000_000;
/// Reaction deadline of the stack as seen on its channels, ns: one 5 ms control period of the
/// vacuum node (eq. 11's "in the same period") plus one period until the board's report of the
/// commanded gate position is published on `vacuum/state`.
pub const STACK_REACTION_NS: u64 = 10_000_000;

const JOINTS: [JointId; 4] = [
    JointId::Extension,
    JointId::Pitch,
    JointId::Yaw,
    JointId::Twist,
];

/// Settings of the mapping.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MappingConfig {
    /// An open, settled gate without a seal for longer than this is a failed attachment, ns.
    pub attach_window_ns: u64,
    /// Joint limits `(lower, upper)` of arm 1 and arm 2 (D m, theta/phi/twist rad).
    pub joint_limits: [([f64; 4], [f64; 4]); 2],
}

impl Default for MappingConfig {
    /// The attach window [`DEFAULT_ATTACH_WINDOW_NS`] and the Table 1 limits of both arms.
    fn default() -> Self {
        Self {
            attach_window_ns: DEFAULT_ATTACH_WINDOW_NS,
            joint_limits: [ArmParams::arm1(), ArmParams::arm2()].map(|p| {
                (
                    p.position_limits.min.to_array(),
                    p.position_limits.max.to_array(),
                )
            }),
        }
    }
}

/// What the mapping remembers of one arm's valve line.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct LineView {
    open: bool,
    sealed: bool,
    sealed_in_opening: bool,
    settled_since_ns: Option<u64>,
    failure_reported: bool,
}

/// Turns stack messages into trace events (see the module docs).
#[derive(Debug, Clone)]
pub struct StackTraceMapper {
    config: MappingConfig,
    last_ns: u64,
    lines: [LineView; 2],
    phases: [Option<WireCode<PhaseCode>>; 2],
    end_effectors_m: [Option<[f64; 3]>; 2],
    stop_engaged: bool,
}

impl StackTraceMapper {
    /// A mapper that has seen nothing: valves closed, no stop.
    pub fn new(config: MappingConfig) -> Self {
        Self {
            config,
            last_ns: 0,
            lines: [LineView::default(); 2],
            phases: [None; 2],
            end_effectors_m: [None; 2],
            stop_engaged: false,
        }
    }

    fn stamp(&mut self, receive_ns: u64) -> u64 {
        self.last_ns = self.last_ns.max(receive_ns);
        self.last_ns
    }

    /// A `vacuum/state` message received at `receive_ns`.
    pub fn vacuum_state(
        &mut self,
        receive_ns: u64,
        state: &VacuumState,
        out: &mut Vec<TraceEvent>,
    ) {
        let stamp_ns = self.stamp(receive_ns);
        for arm in ArmId::ALL {
            let i = arm.index();
            let (inlet, vent) = (2 * i, 2 * i + 1);
            let open = state.valve_open[inlet] == 1;
            let line = &mut self.lines[i];
            if open != line.open {
                out.push(if open {
                    TraceEvent::ValveOpened { stamp_ns, arm }
                } else {
                    TraceEvent::ValveClosed { stamp_ns, arm }
                });
                *line = LineView {
                    open,
                    ..LineView::default()
                };
            }
            if !open {
                continue;
            }
            // An unknown attachment code counts as unsealed, and not as a drop.
            let attachment = state.arm_attachment[i];
            let sealed = attachment == ArmAttachment::Sealed;
            if sealed && !line.sealed {
                out.push(TraceEvent::AttachmentChanged {
                    stamp_ns,
                    arm,
                    sealed: true,
                });
                line.sealed_in_opening = true;
            } else if !sealed && line.sealed {
                out.push(TraceEvent::AttachmentChanged {
                    stamp_ns,
                    arm,
                    sealed: false,
                });
                // `Closed` is the supervisor closing the line (release, or a close the board
                // has not reported yet): not a drop. `Open` with the gate open is.
                if attachment == ArmAttachment::Open && !line.failure_reported {
                    out.push(TraceEvent::FailureDetected {
                        stamp_ns,
                        arm,
                        kind: FailureKind::Dropped,
                    });
                    line.failure_reported = true;
                }
            }
            line.sealed = sealed;
            let settled = state.valve_in_transit[inlet] == 0
                && state.valve_open[vent] == 0
                && state.valve_in_transit[vent] == 0;
            if settled {
                line.settled_since_ns.get_or_insert(stamp_ns);
            }
            if let Some(since_ns) = line.settled_since_ns
                && !line.sealed_in_opening
                && !line.failure_reported
                && stamp_ns.saturating_sub(since_ns) > self.config.attach_window_ns
            {
                out.push(TraceEvent::FailureDetected {
                    stamp_ns,
                    arm,
                    kind: FailureKind::AttachFailed,
                });
                line.failure_reported = true;
            }
        }
    }

    /// An `arm{n}/command` message of `arm` received at `receive_ns`.
    pub fn arm_command(
        &mut self,
        receive_ns: u64,
        arm: ArmId,
        command: &ArmCommand,
        out: &mut Vec<TraceEvent>,
    ) {
        let stamp_ns = self.stamp(receive_ns);
        if command.hold != 0 {
            return;
        }
        let (lower, upper) = self.config.joint_limits[arm.index()];
        for (j, joint) in JOINTS.into_iter().enumerate() {
            out.push(TraceEvent::JointCommand {
                stamp_ns,
                arm,
                joint,
                command: command.joint_position[j],
                lower: lower[j],
                upper: upper[j],
            });
        }
    }

    /// An `arm{n}/state` message of `arm` received at `receive_ns`.
    pub fn arm_state(
        &mut self,
        receive_ns: u64,
        arm: ArmId,
        state: &ArmState,
        out: &mut Vec<TraceEvent>,
    ) {
        let stamp_ns = self.stamp(receive_ns);
        let i = arm.index();
        if self.phases[i] != Some(state.phase) {
            self.phases[i] = Some(state.phase);
            // An unknown phase code changes nothing the monitor judges.
            if let Ok(phase) = state.phase.get() {
                out.push(TraceEvent::PhaseChanged {
                    stamp_ns,
                    arm,
                    phase: CoordinationPhase::from_reported(phase),
                });
            }
        }
        self.end_effectors_m[i] = Some(state.end_effector_in_robot_m);
        if let [Some(arm1_in_robot_m), Some(arm2_in_robot_m)] = self.end_effectors_m {
            out.push(TraceEvent::EndEffectors {
                stamp_ns,
                arm1_in_robot_m,
                arm2_in_robot_m,
            });
        }
    }

    /// A `safety/emergency_stop` message received at `receive_ns`.
    pub fn emergency_stop(
        &mut self,
        receive_ns: u64,
        stop: &EmergencyStop,
        out: &mut Vec<TraceEvent>,
    ) {
        let stamp_ns = self.stamp(receive_ns);
        let engaged = stop.engaged != 0;
        if engaged != self.stop_engaged {
            self.stop_engaged = engaged;
            out.push(TraceEvent::EmergencyStop { stamp_ns, engaged });
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ArmAttachment::{Closed, Open, Sealed};

    const MS: u64 = 1_000_000;

    fn vacuum(open: [bool; 2], attachment: [ArmAttachment; 2]) -> VacuumState {
        VacuumState {
            valve_open: [
                u8::from(open[0]),
                u8::from(!open[0]),
                u8::from(open[1]),
                u8::from(!open[1]),
            ],
            arm_attachment: attachment.map(Into::into),
            ..VacuumState::default()
        }
    }

    #[test]
    fn a_release_is_not_a_drop_but_a_lost_seal_is() {
        let mut m = StackTraceMapper::new(MappingConfig::default());
        let mut out = Vec::new();
        m.vacuum_state(10 * MS, &vacuum([true, false], [Open, Closed]), &mut out);
        m.vacuum_state(60 * MS, &vacuum([true, false], [Sealed, Closed]), &mut out);
        // Released at the drop-off: the supervisor closes, attachment "closed".
        m.vacuum_state(900 * MS, &vacuum([true, false], [Closed, Closed]), &mut out);
        m.vacuum_state(
            905 * MS,
            &vacuum([false, false], [Closed, Closed]),
            &mut out,
        );
        assert!(
            !out.iter()
                .any(|e| matches!(e, TraceEvent::FailureDetected { .. }))
        );
        // A new opening whose seal is lost with the gate open.
        out.clear();
        m.vacuum_state(
            1000 * MS,
            &vacuum([true, false], [Sealed, Closed]),
            &mut out,
        );
        m.vacuum_state(1200 * MS, &vacuum([true, false], [Open, Closed]), &mut out);
        assert_eq!(
            out.last(),
            Some(&TraceEvent::FailureDetected {
                stamp_ns: 1200 * MS,
                arm: ArmId::Arm1,
                kind: FailureKind::Dropped
            })
        );
    }

    #[test]
    fn an_open_line_without_seal_fails_after_the_window_and_stamps_never_go_back() {
        let mut m = StackTraceMapper::new(MappingConfig::default());
        let mut out = Vec::new();
        m.vacuum_state(100 * MS, &vacuum([false, true], [Closed, Open]), &mut out);
        m.vacuum_state(90 * MS, &vacuum([false, true], [Closed, Open]), &mut out);
        assert_eq!(out[0].stamp_ns(), 100 * MS);
        m.vacuum_state(600 * MS, &vacuum([false, true], [Closed, Open]), &mut out);
        assert_eq!(out.len(), 1, "within the window");
        m.vacuum_state(620 * MS, &vacuum([false, true], [Closed, Open]), &mut out);
        assert_eq!(
            out.last(),
            Some(&TraceEvent::FailureDetected {
                stamp_ns: 620 * MS,
                arm: ArmId::Arm2,
                kind: FailureKind::AttachFailed
            })
        );
    }

    #[test]
    fn commands_carry_the_table_1_limits_and_brakes_send_nothing() {
        let mut m = StackTraceMapper::new(MappingConfig::default());
        let mut out = Vec::new();
        let command = ArmCommand {
            joint_position: [0.1, 0.2, 0.3, 0.4],
            ..ArmCommand::default()
        };
        m.arm_command(5, ArmId::Arm2, &command, &mut out);
        let limits = ArmParams::arm2().position_limits;
        assert_eq!(out.len(), 4);
        assert_eq!(
            out[0],
            TraceEvent::JointCommand {
                stamp_ns: 5,
                arm: ArmId::Arm2,
                joint: JointId::Extension,
                command: 0.1,
                lower: limits.min.to_array()[0],
                upper: limits.max.to_array()[0],
            }
        );
        let brake = ArmCommand { hold: 1, ..command };
        m.arm_command(6, ArmId::Arm2, &brake, &mut out);
        assert_eq!(out.len(), 4);
    }
}
