//! End-to-end: recordings written with the recorder's MCAP writer, with and without planted
//! violations, judged by [`check_recording`].

use std::path::{Path, PathBuf};

use harvest_ipc::catalogue::{ARM_COMMAND, ARM_STATE, EMERGENCY_STOP, VACUUM_STATE};
use harvest_ipc::payloads::{
    ArmAttachment, ArmCommand, ArmPhase, ArmState, EmergencyStop, VacuumPolicyCode, VacuumState,
};
use harvest_ipc::{Channel, Payload};
use harvest_recording::schema::TopicInfo;
use harvest_recording::segment_writer::{ChunkCompression, ChunkSettings, SegmentWriter};
use harvest_robot_model::ArmId;
use harvest_robot_model::params::ArmParams;
use harvest_safety::safety_monitor::{MonitorConfig, Violation};
use harvest_safety::trace::JointId;

use crate::mapping::{MappingConfig, STACK_REACTION_NS};
use crate::recording::check_recording;

const MS: u64 = 1_000_000;
const T0: u64 = 1_000 * MS;

/// Writes messages `(log_time, topic index, encoded payload)` into an MCAP file.
struct Recording {
    topics: Vec<TopicInfo>,
    messages: Vec<(u64, usize, Vec<u8>)>,
}

impl Recording {
    fn new() -> Self {
        Self {
            topics: vec![
                TopicInfo::of(VACUUM_STATE),
                TopicInfo::of(ARM_COMMAND[0]),
                TopicInfo::of(ARM_COMMAND[1]),
                TopicInfo::of(ARM_STATE[0]),
                TopicInfo::of(ARM_STATE[1]),
                TopicInfo::of(EMERGENCY_STOP),
            ],
            messages: Vec::new(),
        }
    }

    fn push<T: Payload>(&mut self, t_ms: u64, channel: Channel<T>, value: &T) {
        let index = self
            .topics
            .iter()
            .position(|t| t.spec.topic == channel.spec.topic)
            .expect("known topic");
        let mut data = Vec::new();
        value.encode(&mut data).expect("encode");
        self.messages.push((T0 + t_ms * MS, index, data));
    }

    fn write(mut self, path: &Path) {
        self.messages.sort_by_key(|m| m.0);
        let settings = ChunkSettings {
            compression: ChunkCompression::Lz4,
            compression_level: 0,
            compression_threads: 0,
            chunk_size_bytes: 4096,
        };
        let file = std::fs::File::create(path).expect("create");
        let mut writer = SegmentWriter::new(file, &settings, self.topics.len()).expect("writer");
        for (seq, (t, index, data)) in self.messages.iter().enumerate() {
            writer
                .write_message(*index, &self.topics[*index], seq as u32, *t, *t, data)
                .expect("write");
        }
        writer.finish().expect("finish");
    }
}

fn vacuum(open: [bool; 2], attachment: [ArmAttachment; 2]) -> VacuumState {
    VacuumState {
        valve_open: [
            u8::from(open[0]),
            u8::from(!open[0]),
            u8::from(open[1]),
            u8::from(!open[1]),
        ],
        arm_attachment: attachment.map(Into::into),
        policy: VacuumPolicyCode::Policy2024.into(),
        ..VacuumState::default()
    }
}

fn arm_state(arm: usize, phase: ArmPhase) -> ArmState {
    ArmState {
        arm_id: arm as u8 + 1,
        phase: phase.into(),
        end_effector_in_robot_m: [1.0, if arm == 0 { 0.2 } else { -0.2 }, 0.5],
        ..ArmState::default()
    }
}

fn command(arm: usize, d_m: f64, hold: bool) -> ArmCommand {
    ArmCommand {
        arm_id: arm as u8 + 1,
        hold: u8::from(hold),
        joint_position: [d_m, 0.1, 0.0, 0.0],
        ..ArmCommand::default()
    }
}

/// 500 ms of a harvest: arm 1 attaches at 100 ms (sealed at 150 ms) and releases at 300 ms;
/// arm 2 opens at `arm2_opens_ms` and closes 50 ms later; arm 1 is sent extension
/// `arm1_d_m` at 250 ms; the emergency stop is engaged at 400 ms (valves closed, brakes).
fn harvest(arm2_opens_ms: u64, arm1_d_m: f64) -> Recording {
    let mut r = Recording::new();
    for t in (0..500).step_by(5) {
        let arm1_open = (100..300).contains(&t);
        let arm1 = match t {
            150..295 => ArmAttachment::Sealed,
            100..150 => ArmAttachment::Open,
            _ => ArmAttachment::Closed,
        };
        let arm2_open = (arm2_opens_ms..arm2_opens_ms + 50).contains(&t);
        let arm2 = if arm2_open {
            ArmAttachment::Open
        } else {
            ArmAttachment::Closed
        };
        let mut state = vacuum([arm1_open, arm2_open], [arm1, arm2]);
        if t >= 410 {
            // Emergency stop: the vents close too (every valve closed).
            state.valve_open = [0; 4];
        }
        r.push(t, VACUUM_STATE, &state);
        for arm in 0..2 {
            let stopped = t >= 405;
            r.push(
                t,
                ARM_STATE[arm],
                &arm_state(
                    arm,
                    if stopped {
                        ArmPhase::Stopped
                    } else {
                        ArmPhase::Approach
                    },
                ),
            );
            let d_m = if arm == 0 && t == 250 { arm1_d_m } else { 0.2 };
            r.push(t, ARM_COMMAND[arm], &command(arm, d_m, stopped));
        }
    }
    r.push(
        400,
        EMERGENCY_STOP,
        &EmergencyStop {
            engaged: 1,
            ..EmergencyStop::default()
        },
    );
    r
}

fn temp(name: &str) -> PathBuf {
    std::env::temp_dir().join(format!(
        "harvest_monitor_{}_{name}.mcap",
        std::process::id()
    ))
}

fn judge(recording: Recording, name: &str) -> (crate::MonitorReport, Vec<Violation>) {
    let path = temp(name);
    recording.write(&path);
    let checks = MonitorConfig {
        control_period_ns: STACK_REACTION_NS,
        clearance_m: 0.10,
    };
    let mut live = Vec::new();
    let report = check_recording(&path, MappingConfig::default(), checks, |v| live.push(*v))
        .expect("readable recording");
    let _ = std::fs::remove_file(&path);
    (report, live)
}

#[test]
fn a_clean_recording_has_no_violation() {
    // Arm 2 opens at 200 ms, beside arm 1's sealed apple (eq. 11 allows it).
    let (report, live) = judge(harvest(200, 0.3), "clean");
    assert_eq!(report.violations, vec![]);
    assert!(live.is_empty());
    assert_eq!(report.messages, 100 * 5 + 1);
    assert_eq!(report.skipped_messages, 0);
    // 80 ticks of set-points x 2 arms x 4 joints, an end-effector pair per arm state but the
    // first, phases and valve changes on top.
    assert!(
        report.trace_events > 80 * 8 + 199,
        "{}",
        report.trace_events
    );
    assert!(report.render().contains("0 violation(s)"));
    // The stop at 400 ms: arms report Stopped at 405 ms, every valve closed at 410 ms.
    assert_eq!(report.emergency_stops.len(), 1);
    let stop = report.emergency_stops[0];
    assert_eq!(stop.engaged_ns, T0 + 400 * MS);
    assert!(
        (stop.arms_holding_s.expect("seen") - 0.005).abs() < 1e-9,
        "{stop:?}"
    );
    assert!(
        (stop.valves_closed_s.expect("seen") - 0.010).abs() < 1e-9,
        "{stop:?}"
    );
    assert!(report.render().contains("all valves closed after 10.0 ms"));
}

#[test]
fn the_planted_violations_are_found_and_nothing_else() {
    let limit_m = ArmParams::arm1().position_limits.max.to_array()[0];
    // Arm 2 opens at 120 ms while arm 1 is open and not yet sealed; arm 1 is sent an
    // extension 5 cm beyond its limit at 250 ms.
    let (report, live) = judge(harvest(120, limit_m + 0.05), "planted");
    assert_eq!(
        report.violations,
        vec![
            Violation::OpenedBesideUnsealed {
                stamp_ns: T0 + 120 * MS,
                arm: ArmId::Arm2
            },
            // Arm 1 seals at 150 ms: the pair was open and unsealed from 120 ms, noticed at the
            // first event past the 10 ms deadline.
            Violation::BothOpenUnsealed {
                since_ns: T0 + 120 * MS,
                noticed_ns: T0 + 135 * MS
            },
            Violation::JointOutOfLimits {
                stamp_ns: T0 + 250 * MS,
                arm: ArmId::Arm1,
                joint: JointId::Extension,
                command: limit_m + 0.05,
                lower: ArmParams::arm1().position_limits.min.to_array()[0],
                upper: limit_m,
            },
        ]
    );
    assert_eq!(live, report.violations, "reported as they were found");
    assert!(report.render().contains("3 violation(s)"));
}

#[test]
fn a_message_with_a_foreign_schema_is_skipped_and_a_missing_file_is_an_error() {
    let mut r = Recording::new();
    r.topics[0].spec.type_name = "other.Type";
    r.push(
        0,
        VACUUM_STATE,
        &vacuum([true, true], [ArmAttachment::Open; 2]),
    );
    let (report, _) = judge(r, "foreign");
    assert_eq!((report.messages, report.skipped_messages), (0, 1));
    let missing = check_recording(
        &temp("missing"),
        MappingConfig::default(),
        MonitorConfig::default(),
        |_| {},
    );
    assert!(missing.is_err());
}
