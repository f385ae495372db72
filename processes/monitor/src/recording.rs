//! `harvest monitor --recording FILE.mcap`: the monitored channels of a recording, in file
//! order, through the recorder's damage-tolerant scanner ([`harvest_recording::scan`]) and the
//! payload codec, judged as the live monitor judges them (receive time = the message's
//! `log_time`). A message whose schema is not the catalogue's for its topic, or that does not
//! decode, is skipped and counted.

use std::ops::ControlFlow;
use std::path::Path;

use harvest_ipc::catalogue::{ARM_COMMAND, ARM_STATE, EMERGENCY_STOP, VACUUM_STATE};
use harvest_recording::payload_codec::decode_scanned as decode;
use harvest_recording::scan::{ScanItem, ScanOptions, scan_file};
use harvest_recording::time_base::FileTimeBase;
use harvest_robot_model::ArmId;
use harvest_safety::safety_monitor::{MonitorConfig, Violation};

use crate::error::MonitorError;
use crate::mapping::MappingConfig;
use crate::stack_monitor::{MonitorReport, StackMessage, StackMonitor};

/// Which monitored channel a topic is, if any.
#[derive(Debug, Clone, Copy)]
enum Topic {
    Vacuum,
    Command(ArmId),
    State(ArmId),
    Stop,
}

fn topic_of(name: &str) -> Option<Topic> {
    if name == VACUUM_STATE.spec.topic {
        return Some(Topic::Vacuum);
    }
    if name == EMERGENCY_STOP.spec.topic {
        return Some(Topic::Stop);
    }
    for arm in ArmId::ALL {
        if name == ARM_COMMAND[arm.index()].spec.topic {
            return Some(Topic::Command(arm));
        }
        if name == ARM_STATE[arm.index()].spec.topic {
            return Some(Topic::State(arm));
        }
    }
    None
}

/// Judges the recording at `path`; `on_violation` sees each violation when it is found.
pub fn check_recording(
    path: &Path,
    mapping: MappingConfig,
    checks: MonitorConfig,
    mut on_violation: impl FnMut(&Violation),
) -> Result<MonitorReport, MonitorError> {
    let mut monitor = StackMonitor::new(mapping, checks);
    let mut failure = None;
    let mut end_ns = 0;
    // Log times may be wall-clock (stack stamp + the session's offset): the rules compare
    // them with payload stamps, so they are judged on the stack clock.
    let mut time = FileTimeBase::default();
    let outcome = scan_file(path, ScanOptions::default(), |item| {
        let message = match item {
            ScanItem::Message(message) => message,
            ScanItem::Metadata(record) => {
                time.observe(record);
                return ControlFlow::Continue(());
            }
            _ => return ControlFlow::Continue(()),
        };
        let Some(topic) = topic_of(&message.channel.topic) else {
            return ControlFlow::Continue(());
        };
        let t = time.stack_ns(message.log_time);
        end_ns = end_ns.max(t);
        let result = match topic {
            Topic::Vacuum => decode(VACUUM_STATE, &message)
                .map(|v| monitor.feed(t, StackMessage::Vacuum(&v)).map(<[_]>::to_vec)),
            Topic::Command(arm) => decode(ARM_COMMAND[arm.index()], &message).map(|c| {
                monitor
                    .feed(t, StackMessage::Command(arm, &c))
                    .map(<[_]>::to_vec)
            }),
            Topic::State(arm) => decode(ARM_STATE[arm.index()], &message).map(|s| {
                monitor
                    .feed(t, StackMessage::State(arm, &s))
                    .map(<[_]>::to_vec)
            }),
            Topic::Stop => decode(EMERGENCY_STOP, &message)
                .map(|s| monitor.feed(t, StackMessage::Stop(&s)).map(<[_]>::to_vec)),
        };
        match result {
            None => monitor.skip(),
            Some(Ok(found)) => found.iter().for_each(&mut on_violation),
            Some(Err(error)) => {
                failure = Some(error.to_string());
                return ControlFlow::Break(());
            }
        }
        ControlFlow::Continue(())
    })
    .map_err(|error| MonitorError::Recording {
        path: path.to_path_buf(),
        message: error.to_string(),
    })?;
    if let Some(message) = failure {
        return Err(MonitorError::Recording {
            path: path.to_path_buf(),
            message,
        });
    }
    for damaged in &outcome.damaged_chunks {
        tracing::warn!(offset = damaged.offset, reason = %damaged.reason, "damaged chunk skipped");
    }
    let before = monitor.violations().len();
    let report = monitor.finish(end_ns);
    report.violations[before..].iter().for_each(on_violation);
    Ok(report)
}

/// The `safety/violation` messages a monitor with `mapping`, `checks` and `action` would have
/// published on the recording `files` (segments in order, each judged from a fresh monitor;
/// headers left to a publisher): what `harvest replay --check` compares with the recorded
/// ones.
pub fn violation_messages(
    files: &[std::path::PathBuf],
    mapping: MappingConfig,
    checks: MonitorConfig,
    action: harvest_ipc::payloads::ViolationAction,
) -> Result<Vec<harvest_ipc::payloads::SafetyViolation>, MonitorError> {
    let mut messages = Vec::new();
    for file in files {
        check_recording(file, mapping, checks, |violation| {
            let mut message = harvest_ipc::payloads::SafetyViolation::default();
            crate::violation_message::fill_message(&mut message, violation, action);
            messages.push(message);
        })?;
    }
    Ok(messages)
}
