//! An independent checker of harvesting traces ([`TraceEvent`]).
//!
//! It shares no logic with the policies or the pressure inference: it keeps its own view of
//! which valves are open and which cups are sealed, built only from the events, and reports
//! - [`Violation::OpenedBesideUnsealed`]: a valve opened while the other arm's valve was open
//!   without a seal (two attachment attempts at once, eq. 11 clauses 3-4);
//! - [`Violation::BothOpenUnsealed`]: both valves open with neither cup sealed for longer than
//!   one control period (a seal lost next to an attempt must be answered within the period);
//! - [`Violation::FailureNotClosed`]: a valve still open one control period after a failure
//!   was detected on its arm (eq. 11 clauses 1-2);
//! - [`Violation::JointOutOfLimits`]: a joint command outside the limits it was sent with;
//! - [`Violation::EndEffectorsTooClose`]: the two end-effectors closer than the clearance;
//! - [`Violation::ValveOpenDuringEmergencyStop`]: a valve opened while the emergency stop is
//!   engaged, or still open one control period after it was engaged;
//! - [`Violation::MovedDuringEmergencyStop`]: a joint set-point sent to an arm more than one
//!   control period after the emergency stop was engaged (the drives must brake).
//!
//! A closed valve vents the tube, so it ends any seal on that arm.

use crate::trace::{JointId, TraceEvent};
use harvest_robot_model::ArmId;
use harvest_robot_model::FailureKind;
use serde::{Deserialize, Serialize};
use thiserror::Error;

/// Settings of the monitor.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MonitorConfig {
    /// Reaction deadline, ns. Default 5 ms: one period of the 200 Hz control loop
    /// (section 2.2).
    pub control_period_ns: u64,
    /// Minimum distance between the two end-effectors, m. Default 0.10 m (choice: the arms'
    /// end-effectors sit 0.22 m apart at zero yaw per Table 1; 0.10 m leaves room for the
    /// soft cups and tracking error).
    pub clearance_m: f64,
}

impl Default for MonitorConfig {
    fn default() -> Self {
        MonitorConfig {
            control_period_ns: 5_000_000,
            clearance_m: 0.10,
        }
    }
}

/// A safety rule broken by a trace.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Violation {
    /// `arm` opened its valve while the other arm's valve was open and unsealed.
    OpenedBesideUnsealed {
        /// Time of the opening, ns.
        stamp_ns: u64,
        /// The arm that opened.
        arm: ArmId,
    },
    /// Both valves open, neither sealed, from `since_ns` for longer than one control period.
    BothOpenUnsealed {
        /// Start of the condition, ns.
        since_ns: u64,
        /// First event time at which it had lasted too long, ns.
        noticed_ns: u64,
    },
    /// A valve was not closed by `deadline_ns` after a failure on its arm.
    FailureNotClosed {
        /// The arm.
        arm: ArmId,
        /// The failure.
        kind: FailureKind,
        /// When it was detected, ns.
        failure_ns: u64,
        /// When the valve had to be closed, ns.
        deadline_ns: u64,
    },
    /// A joint command outside its limits (or not finite).
    JointOutOfLimits {
        /// Time of the command, ns.
        stamp_ns: u64,
        /// The arm.
        arm: ArmId,
        /// The joint.
        joint: JointId,
        /// The command.
        command: f64,
        /// Lower limit.
        lower: f64,
        /// Upper limit.
        upper: f64,
    },
    /// A valve opened while the emergency stop was engaged, or was still open one control
    /// period after it was engaged.
    ValveOpenDuringEmergencyStop {
        /// The arm whose valve.
        arm: ArmId,
        /// When the stop was engaged, ns.
        stop_ns: u64,
        /// When the valve was seen open, ns.
        stamp_ns: u64,
    },
    /// A joint set-point was sent more than one control period after the emergency stop was
    /// engaged (reported once per arm and engagement).
    MovedDuringEmergencyStop {
        /// The arm.
        arm: ArmId,
        /// When the stop was engaged, ns.
        stop_ns: u64,
        /// The set-point's time, ns.
        stamp_ns: u64,
    },
    /// The end-effectors came closer than the clearance (or a position was not finite).
    EndEffectorsTooClose {
        /// Time of validity, ns.
        stamp_ns: u64,
        /// Their distance, m.
        distance_m: f64,
        /// The required clearance, m.
        clearance_m: f64,
    },
}

impl std::fmt::Display for Violation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let ms = |ns: u64| ns as f64 * 1e-6;
        match *self {
            Violation::OpenedBesideUnsealed { stamp_ns, arm } => write!(
                f,
                "{arm} opened its valve at {:.1} ms while the other arm's valve was open with no \
                 seal",
                ms(stamp_ns)
            ),
            Violation::BothOpenUnsealed {
                since_ns,
                noticed_ns,
            } => write!(
                f,
                "both valves open with neither cup sealed from {:.1} ms (still at {:.1} ms)",
                ms(since_ns),
                ms(noticed_ns)
            ),
            Violation::FailureNotClosed {
                arm,
                kind,
                failure_ns,
                deadline_ns,
            } => write!(
                f,
                "{arm}: {kind} at {:.1} ms but the valve was still open at the {:.1} ms deadline",
                ms(failure_ns),
                ms(deadline_ns)
            ),
            Violation::JointOutOfLimits {
                stamp_ns,
                arm,
                joint,
                command,
                lower,
                upper,
            } => write!(
                f,
                "{arm}: {joint:?} commanded to {command} at {:.1} ms, outside [{lower}, {upper}]",
                ms(stamp_ns)
            ),
            Violation::EndEffectorsTooClose {
                stamp_ns,
                distance_m,
                clearance_m,
            } => write!(
                f,
                "end-effectors {distance_m:.3} m apart at {:.1} ms (clearance {clearance_m} m)",
                ms(stamp_ns)
            ),
            Violation::ValveOpenDuringEmergencyStop {
                arm,
                stop_ns,
                stamp_ns,
            } => write!(
                f,
                "{arm}: valve open at {:.1} ms, emergency stop engaged at {:.1} ms",
                ms(stamp_ns),
                ms(stop_ns)
            ),
            Violation::MovedDuringEmergencyStop {
                arm,
                stop_ns,
                stamp_ns,
            } => write!(
                f,
                "{arm}: joint set-point sent at {:.1} ms, emergency stop engaged at {:.1} ms",
                ms(stamp_ns),
                ms(stop_ns)
            ),
        }
    }
}

/// A trace the monitor cannot judge.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Error)]
pub enum TraceError {
    /// Events must come in time order.
    #[error("trace event at {stamp_ns} ns comes after one at {previous_ns} ns")]
    OutOfOrder {
        /// Stamp of the refused event, ns.
        stamp_ns: u64,
        /// Stamp of the previous event, ns.
        previous_ns: u64,
    },
}

/// The streaming checker. Feed events in time order with [`SafetyMonitor::observe`], then
/// call [`SafetyMonitor::finish`] with the end of the trace.
#[derive(Debug, Clone)]
pub struct SafetyMonitor {
    config: MonitorConfig,
    last_ns: Option<u64>,
    open: [bool; 2],
    sealed: [bool; 2],
    /// Detected failure waiting for its valve to close: (detection time, kind).
    pending_failure: [Option<(u64, FailureKind)>; 2],
    /// Start of the both-open-unsealed condition, and whether it has been reported.
    unsealed_pair_since: Option<(u64, bool)>,
    /// When the engaged emergency stop began, and per arm whether its open valve / its motion
    /// has been reported during this engagement.
    stop: Option<(u64, [bool; 2], [bool; 2])>,
    violations: Vec<Violation>,
}

impl SafetyMonitor {
    /// A monitor with both valves closed.
    pub fn new(config: MonitorConfig) -> Self {
        SafetyMonitor {
            config,
            last_ns: None,
            open: [false; 2],
            sealed: [false; 2],
            pending_failure: [None; 2],
            unsealed_pair_since: None,
            stop: None,
            violations: Vec::new(),
        }
    }

    /// Violations found so far, in the order found.
    pub fn violations(&self) -> &[Violation] {
        &self.violations
    }

    /// Judge one event. An out-of-order event is refused and changes nothing.
    pub fn observe(&mut self, event: &TraceEvent) -> Result<(), TraceError> {
        let stamp_ns = event.stamp_ns();
        if let Some(previous_ns) = self.last_ns
            && stamp_ns < previous_ns
        {
            return Err(TraceError::OutOfOrder {
                stamp_ns,
                previous_ns,
            });
        }
        self.last_ns = Some(stamp_ns);
        self.check_deadlines(stamp_ns);
        match *event {
            TraceEvent::ValveOpened { arm, .. } => {
                self.report_valve_open_during_stop(arm, stamp_ns);
                let other = arm.other().index();
                if self.open[other] && !self.sealed[other] {
                    self.violations
                        .push(Violation::OpenedBesideUnsealed { stamp_ns, arm });
                }
                self.open[arm.index()] = true;
                self.sealed[arm.index()] = false;
            }
            TraceEvent::ValveClosed { arm, .. } => {
                self.open[arm.index()] = false;
                self.sealed[arm.index()] = false;
                self.pending_failure[arm.index()] = None;
            }
            TraceEvent::AttachmentChanged { arm, sealed, .. } => {
                self.sealed[arm.index()] = sealed && self.open[arm.index()];
            }
            TraceEvent::FailureDetected { arm, kind, .. } => {
                self.sealed[arm.index()] = false;
                if self.open[arm.index()] && self.pending_failure[arm.index()].is_none() {
                    self.pending_failure[arm.index()] = Some((stamp_ns, kind));
                }
            }
            TraceEvent::PhaseChanged { .. } => {}
            TraceEvent::EmergencyStop { engaged, .. } => match (engaged, self.stop) {
                (true, None) => self.stop = Some((stamp_ns, [false; 2], [false; 2])),
                (false, Some(_)) => self.stop = None,
                _ => {}
            },
            TraceEvent::JointCommand {
                arm,
                joint,
                command,
                lower,
                upper,
                ..
            } => {
                if let Some((stop_ns, _, motion_reported)) = self.stop.as_mut()
                    && stamp_ns > stop_ns.saturating_add(self.config.control_period_ns)
                    && !motion_reported[arm.index()]
                {
                    motion_reported[arm.index()] = true;
                    self.violations.push(Violation::MovedDuringEmergencyStop {
                        arm,
                        stop_ns: *stop_ns,
                        stamp_ns,
                    });
                }
                let inside = command.is_finite() && lower <= command && command <= upper;
                if !inside {
                    self.violations.push(Violation::JointOutOfLimits {
                        stamp_ns,
                        arm,
                        joint,
                        command,
                        lower,
                        upper,
                    });
                }
            }
            TraceEvent::EndEffectors {
                arm1_in_robot_m,
                arm2_in_robot_m,
                ..
            } => {
                let distance_m = (0..3)
                    .map(|i| (arm1_in_robot_m[i] - arm2_in_robot_m[i]).powi(2))
                    .sum::<f64>()
                    .sqrt();
                // A NaN distance (non-finite position) counts as too close.
                if distance_m.is_nan() || distance_m < self.config.clearance_m {
                    self.violations.push(Violation::EndEffectorsTooClose {
                        stamp_ns,
                        distance_m,
                        clearance_m: self.config.clearance_m,
                    });
                }
            }
        }
        self.update_pair_condition(stamp_ns);
        Ok(())
    }

    /// End of the trace at `end_ns`: deadlines that expired before it are judged. Returns all
    /// violations.
    pub fn finish(&mut self, end_ns: u64) -> &[Violation] {
        let end_ns = end_ns.max(self.last_ns.unwrap_or(0));
        self.check_deadlines(end_ns);
        &self.violations
    }

    /// Judge the deadlines that expire before `now_ns` given the state since the last event.
    fn check_deadlines(&mut self, now_ns: u64) {
        let period = self.config.control_period_ns;
        for arm in ArmId::ALL {
            if let Some((failure_ns, kind)) = self.pending_failure[arm.index()] {
                let deadline_ns = failure_ns.saturating_add(period);
                if now_ns > deadline_ns {
                    self.violations.push(Violation::FailureNotClosed {
                        arm,
                        kind,
                        failure_ns,
                        deadline_ns,
                    });
                    self.pending_failure[arm.index()] = None;
                }
            }
        }
        if let Some((stop_ns, _, _)) = self.stop
            && now_ns > stop_ns.saturating_add(period)
        {
            for arm in ArmId::ALL {
                if self.open[arm.index()] {
                    self.report_valve_open_during_stop(arm, now_ns);
                }
            }
        }
        if let Some((since_ns, reported)) = self.unsealed_pair_since
            && !reported
            && now_ns > since_ns.saturating_add(period)
        {
            self.violations.push(Violation::BothOpenUnsealed {
                since_ns,
                noticed_ns: now_ns,
            });
            self.unsealed_pair_since = Some((since_ns, true));
        }
    }

    /// While an emergency stop is engaged, `arm`'s valve open at `stamp_ns` is a violation,
    /// reported once per arm and engagement.
    fn report_valve_open_during_stop(&mut self, arm: ArmId, stamp_ns: u64) {
        if let Some((stop_ns, valve_reported, _)) = self.stop.as_mut()
            && !valve_reported[arm.index()]
        {
            valve_reported[arm.index()] = true;
            self.violations
                .push(Violation::ValveOpenDuringEmergencyStop {
                    arm,
                    stop_ns: *stop_ns,
                    stamp_ns,
                });
        }
    }

    fn update_pair_condition(&mut self, now_ns: u64) {
        let both_unsealed = self.open[0] && self.open[1] && !self.sealed[0] && !self.sealed[1];
        match (both_unsealed, self.unsealed_pair_since) {
            (true, None) => self.unsealed_pair_since = Some((now_ns, false)),
            (false, Some(_)) => self.unsealed_pair_since = None,
            _ => {}
        }
    }
}

/// Check a whole trace ending at its last event.
pub fn check_trace(
    events: &[TraceEvent],
    config: MonitorConfig,
) -> Result<Vec<Violation>, TraceError> {
    let mut monitor = SafetyMonitor::new(config);
    for event in events {
        monitor.observe(event)?;
    }
    let end_ns = events.last().map_or(0, TraceEvent::stamp_ns);
    Ok(monitor.finish(end_ns).to_vec())
}

#[cfg(test)]
mod tests {
    use super::*;
    use TraceEvent::*;

    const MS: u64 = 1_000_000;
    const A1: ArmId = ArmId::Arm1;
    const A2: ArmId = ArmId::Arm2;

    fn check(events: &[TraceEvent]) -> Vec<Violation> {
        check_trace(events, MonitorConfig::default()).expect("ordered")
    }

    fn opened(stamp_ns: u64, arm: ArmId) -> TraceEvent {
        ValveOpened { stamp_ns, arm }
    }

    fn closed(stamp_ns: u64, arm: ArmId) -> TraceEvent {
        ValveClosed { stamp_ns, arm }
    }

    fn attachment(stamp_ns: u64, arm: ArmId, sealed: bool) -> TraceEvent {
        AttachmentChanged {
            stamp_ns,
            arm,
            sealed,
        }
    }

    fn failure(stamp_ns: u64, arm: ArmId, kind: FailureKind) -> TraceEvent {
        FailureDetected {
            stamp_ns,
            arm,
            kind,
        }
    }

    #[test]
    fn attempt_beside_a_sealed_apple_is_fine_beside_an_unsealed_one_is_not() {
        let ok = [
            opened(0, A1),
            attachment(50 * MS, A1, true),
            opened(50 * MS, A2),
            closed(300 * MS, A2),
            closed(2000 * MS, A1),
        ];
        assert_eq!(check(&ok), vec![]);
        let bad = [opened(0, A1), opened(10 * MS, A2), closed(12 * MS, A2)];
        assert_eq!(
            check(&bad),
            vec![Violation::OpenedBesideUnsealed {
                stamp_ns: 10 * MS,
                arm: A2
            }]
        );
    }

    #[test]
    fn a_drop_beside_an_attempt_must_be_closed_within_the_period() {
        let base = [
            opened(0, A1),
            attachment(50 * MS, A1, true),
            opened(60 * MS, A2),
            attachment(100 * MS, A1, false),
            failure(100 * MS, A1, FailureKind::Dropped),
        ];
        // Closed exactly at the deadline: fine.
        let mut on_time = base.to_vec();
        on_time.push(closed(105 * MS, A1));
        on_time.push(closed(400 * MS, A2));
        assert_eq!(check(&on_time), vec![]);
        // One nanosecond late: both rules fire.
        let mut late = base.to_vec();
        late.push(closed(105 * MS + 1, A1));
        let v = check(&late);
        assert!(v.contains(&Violation::FailureNotClosed {
            arm: A1,
            kind: FailureKind::Dropped,
            failure_ns: 100 * MS,
            deadline_ns: 105 * MS,
        }));
        assert!(v.contains(&Violation::BothOpenUnsealed {
            since_ns: 100 * MS,
            noticed_ns: 105 * MS + 1,
        }));
        assert_eq!(v.len(), 2);
    }

    #[test]
    fn failure_left_open_is_caught_at_finish_and_closed_valve_failures_are_ignored() {
        let mut m = SafetyMonitor::new(MonitorConfig::default());
        for e in [
            opened(0, A2),
            failure(250 * MS, A2, FailureKind::AttachFailed),
            // A failure reported on an arm whose valve is closed needs nothing.
            failure(250 * MS, A1, FailureKind::Dropped),
        ] {
            m.observe(&e).expect("ordered");
        }
        assert_eq!(m.finish(254 * MS).len(), 0);
        assert_eq!(
            m.finish(256 * MS),
            &[Violation::FailureNotClosed {
                arm: A2,
                kind: FailureKind::AttachFailed,
                failure_ns: 250 * MS,
                deadline_ns: 255 * MS,
            }]
        );
    }

    #[test]
    fn joint_limits_and_clearance() {
        let events = [
            JointCommand {
                stamp_ns: 0,
                arm: A1,
                joint: JointId::Extension,
                command: 0.3,
                lower: -0.02,
                upper: 0.6,
            },
            JointCommand {
                stamp_ns: 1,
                arm: A1,
                joint: JointId::Extension,
                command: 0.61,
                lower: -0.02,
                upper: 0.6,
            },
            JointCommand {
                stamp_ns: 2,
                arm: A2,
                joint: JointId::Pitch,
                command: f64::NAN,
                lower: -0.26,
                upper: 0.52,
            },
            EndEffectors {
                stamp_ns: 3,
                arm1_in_robot_m: [0.5, 0.11, 0.2],
                arm2_in_robot_m: [0.5, -0.11, 0.2],
            },
            EndEffectors {
                stamp_ns: 4,
                arm1_in_robot_m: [0.5, 0.03, 0.2],
                arm2_in_robot_m: [0.5, -0.03, 0.2],
            },
        ];
        let v = check(&events);
        assert_eq!(v.len(), 3, "{v:?}");
        assert!(
            matches!(v[0], Violation::JointOutOfLimits { stamp_ns: 1, command, .. } if command == 0.61)
        );
        assert!(matches!(
            v[1],
            Violation::JointOutOfLimits {
                stamp_ns: 2,
                arm: ArmId::Arm2,
                ..
            }
        ));
        assert!(
            matches!(v[2], Violation::EndEffectorsTooClose { stamp_ns: 4, distance_m, .. }
            if (distance_m - 0.06).abs() < 1e-12)
        );
    }

    #[test]
    fn emergency_stop_must_close_the_valves_and_brake_the_arms_within_one_period() {
        let joint = |stamp_ns, arm| JointCommand {
            stamp_ns,
            arm,
            joint: JointId::Pitch,
            command: 0.1,
            lower: -1.0,
            upper: 1.0,
        };
        let stop = |stamp_ns, engaged| EmergencyStop { stamp_ns, engaged };
        // Valve closed and last set-point within the period: fine.
        let ok = [
            opened(0, A1),
            stop(100 * MS, true),
            joint(103 * MS, A1),
            closed(105 * MS, A1),
            EndEffectors {
                stamp_ns: 400 * MS,
                arm1_in_robot_m: [1.0, 0.2, 0.0],
                arm2_in_robot_m: [1.0, -0.2, 0.0],
            },
            stop(500 * MS, false),
            joint(510 * MS, A2),
            opened(520 * MS, A2),
        ];
        assert_eq!(check(&ok), vec![]);
        // Valve left open, a later set-point, and a valve opened while engaged.
        let bad = [
            opened(0, A1),
            stop(100 * MS, true),
            joint(120 * MS, A2),
            joint(125 * MS, A2),
            opened(130 * MS, A2),
        ];
        assert_eq!(
            check(&bad),
            vec![
                Violation::ValveOpenDuringEmergencyStop {
                    arm: A1,
                    stop_ns: 100 * MS,
                    stamp_ns: 120 * MS
                },
                Violation::MovedDuringEmergencyStop {
                    arm: A2,
                    stop_ns: 100 * MS,
                    stamp_ns: 120 * MS
                },
                Violation::ValveOpenDuringEmergencyStop {
                    arm: A2,
                    stop_ns: 100 * MS,
                    stamp_ns: 130 * MS
                },
                Violation::OpenedBesideUnsealed {
                    stamp_ns: 130 * MS,
                    arm: A2
                },
            ]
        );
        assert!(check(&bad)[0].to_string().contains("emergency stop"));
    }

    #[test]
    fn out_of_order_events_are_refused() {
        let mut m = SafetyMonitor::new(MonitorConfig::default());
        m.observe(&opened(10, A1)).expect("first");
        assert_eq!(
            m.observe(&opened(5, A2)),
            Err(TraceError::OutOfOrder {
                stamp_ns: 5,
                previous_ns: 10
            })
        );
        assert!(m.violations().is_empty());
    }

    #[test]
    fn config_refuses_unknown_keys() {
        let cfg: MonitorConfig =
            toml::from_str("control_period_ns = 5000000\nclearance_m = 0.12\n").expect("valid");
        assert_eq!(cfg.clearance_m, 0.12);
        assert!(toml::from_str::<MonitorConfig>("period_ns = 1\nclearance_m = 0.1\n").is_err());
    }
}
