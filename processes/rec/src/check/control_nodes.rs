//! The control nodes the check re-runs: each arm and the vacuum supervisor, on recorded
//! devices, with which recorded messages on a shared channel are theirs.

use harvest_arm::task::{ArmDevices, ArmTask};
use harvest_ipc::ArmId;
use harvest_ipc::catalogue::{ARM_TICKS, HARVEST_EVENTS, VACUUM_TICKS, VALVE_REQUEST};
use harvest_ipc::payloads::{HarvestEvent, HarvestEventSource, ValveRequest};
use harvest_vacuum::task::{BoardDevices, VacuumTask};

use crate::check::control_rerun::{ControlNode, ControlRerun, decode};
use crate::check::recorded_devices::{RecordedBoard, RecordedServos};
use crate::check::report::CheckError;

/// Builds a node for the check (the live process's arguments applied).
pub type Build<T> = Box<dyn Fn() -> Result<T, String>>;

/// Whether a recorded message on a shared channel was written by `source`; messages of
/// single-writer channels are always the node's.
fn written_by(source: HarvestEventSource, topic: &str, bytes: &[u8]) -> bool {
    if topic == HARVEST_EVENTS.spec.topic {
        decode::<HarvestEvent>(bytes).is_some_and(|event| event.source.get() == Ok(source))
    } else if topic == VALVE_REQUEST.spec.topic {
        let arm = match source {
            HarvestEventSource::Arm1 => 1,
            HarvestEventSource::Arm2 => 2,
            _ => 0,
        };
        decode::<ValveRequest>(bytes).is_some_and(|request| request.arm_id == arm)
    } else {
        true
    }
}

fn arm1_owns(topic: &str, bytes: &[u8]) -> bool {
    written_by(HarvestEventSource::Arm1, topic, bytes)
}

fn arm2_owns(topic: &str, bytes: &[u8]) -> bool {
    written_by(HarvestEventSource::Arm2, topic, bytes)
}

fn vacuum_owns(topic: &str, bytes: &[u8]) -> bool {
    written_by(HarvestEventSource::Vacuum, topic, bytes)
}

/// Arm `arm` for the check: `build` makes its task as the live process did.
pub fn arm_rerun(
    arm: ArmId,
    build: Build<ArmTask<RecordedServos>>,
    max_read_failures: u32,
) -> Box<dyn ControlRerun> {
    let (name, owns): (&'static str, _) = match arm {
        ArmId::Arm1 => ("arm1", arm1_owns as fn(&str, &[u8]) -> bool),
        ArmId::Arm2 => ("arm2", arm2_owns as fn(&str, &[u8]) -> bool),
    };
    Box::new(ControlNode {
        name,
        ticks: ARM_TICKS[arm.index()],
        build: Box::new(move || {
            let task = build().map_err(CheckError::Settings)?;
            Ok((task, ArmDevices(RecordedServos::default())))
        }),
        max_read_failures,
        owns,
    })
}

/// The vacuum supervisor for the check: `build` makes its task as the live process did.
pub fn vacuum_rerun(
    build: Build<VacuumTask<RecordedBoard>>,
    max_read_failures: u32,
) -> Box<dyn ControlRerun> {
    Box::new(ControlNode {
        name: "vacuum",
        ticks: VACUUM_TICKS,
        build: Box::new(move || {
            let task = build().map_err(CheckError::Settings)?;
            Ok((task, BoardDevices::new(RecordedBoard::default())))
        }),
        max_read_failures,
        owns: vacuum_owns,
    })
}
