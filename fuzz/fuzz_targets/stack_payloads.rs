//! Any bytes as the payloads the vacuum supervisor and both arms read from shared memory, tick
//! after tick (every payload of every tick is cut from the input, so any bit pattern lands in
//! any field): no panic, servo set-points finite and inside the Table 1 joint limits, both
//! source valves closed and both arms holding under the emergency stop, no valve opened beside
//! the other arm's open unsealed one, never both open unsealed for two periods.
#![no_main]

use harvest_arm::node::{ArmNode, ArmNodeConfig, ArmNodeInput, EncoderSample, OtherArmInput, ServoOrder};
use harvest_ipc::Payload;
use harvest_ipc::payloads::{
    AppleDetections, ArmState, ArmTarget, EmergencyStop, VacuumState, ValveGrant, ValveRequest,
};
use harvest_robot_model::ArmId;
use harvest_robot_model::params::{ArmId as ArmNumber, ArmParams};
use harvest_vacuum::node::{BoardReadings, VacuumNode, VacuumNodeConfig, VacuumNodeInput};
use harvest_vacuum::policy::PolicyKind;
use harvest_vacuum::pressure::AttachmentState;
use libfuzzer_sys::fuzz_target;

/// Cuts payloads out of the input, wrapping around.
struct Bytes<'a> {
    data: &'a [u8],
    at: usize,
}

impl Bytes<'_> {
    fn payload<T: Payload>(&mut self) -> Box<T> {
        let mut value = harvest_ipc::payload::boxed_zeroed::<T>();
        // SAFETY: `value` is a valid, uniquely borrowed `T` of `size_of::<T>()` bytes, and every
        // bit pattern is a valid `T` (the `Payload` contract).
        let raw = unsafe {
            std::slice::from_raw_parts_mut((&mut *value as *mut T).cast::<u8>(), std::mem::size_of::<T>())
        };
        for byte in raw.iter_mut() {
            *byte = self.data[self.at % self.data.len()];
            self.at += 1;
        }
        value
    }

    fn byte(&mut self) -> u8 {
        let byte = self.data[self.at % self.data.len()];
        self.at += 1;
        byte
    }

    fn f64(&mut self) -> f64 {
        f64::from_le_bytes(std::array::from_fn(|_| self.byte()))
    }
}

fuzz_target!(|data: &[u8]| {
    if data.len() < 2 {
        return;
    }
    let ticks = usize::from(data[0]).min(200);
    let policy = [PolicyKind::Baseline, PolicyKind::V2023, PolicyKind::V2024][usize::from(data[1]) % 3];
    let mut bytes = Bytes { data: &data[2..], at: 0 };
    if bytes.data.is_empty() {
        return;
    }
    let arm_config = ArmNodeConfig::default();
    let mut vacuum = VacuumNode::new(
        VacuumNodeConfig { policy, ..VacuumNodeConfig::default() },
        Box::new(move |arm: ArmId, centre: &[f64; 3], radius_m: f64| {
            harvest_arm::node::pick_reachable(
                [ArmNumber::Arm1, ArmNumber::Arm2][arm.index()],
                *centre,
                radius_m,
                &arm_config,
            )
        }),
    )
    .expect("vacuum node");
    let numbers = [ArmNumber::Arm1, ArmNumber::Arm2];
    let mut arms = numbers.map(|arm| ArmNode::new(arm, arm_config).expect("arm node"));
    let params = numbers.map(ArmParams::for_arm);
    let mut open_before = [false; 2];
    let mut both_open_unsealed = 0;
    for tick in 0..ticks {
        let now_ns = 10_000_000_000 + tick as u64 * 5_000_000;
        let estop = bytes.payload::<EmergencyStop>();
        // As the processes read it: `engaged` not 0 (through its byte, whatever its type).
        // SAFETY: the offset is inside the valid, initialized `EmergencyStop`.
        let engaged = unsafe {
            *(&*estop as *const EmergencyStop)
                .cast::<u8>()
                .add(std::mem::offset_of!(EmergencyStop, engaged))
        } != 0;
        let states = [bytes.payload::<ArmState>(), bytes.payload::<ArmState>()];
        let requests = [bytes.payload::<ValveRequest>(), bytes.payload::<ValveRequest>()];
        let detections = (bytes.byte() & 3 == 0).then(|| bytes.payload::<AppleDetections>());
        let readings = BoardReadings {
            stamp_ns: now_ns,
            valve_open: std::array::from_fn(|_| bytes.byte() & 1 == 1),
            valve_in_transit: std::array::from_fn(|_| bytes.byte() & 1 == 1),
            pressure_mmh2o: std::array::from_fn(|_| bytes.f64() as f32),
        };
        let out = vacuum
            .step(&VacuumNodeInput {
                now_ns,
                arm_states: [Some(&states[0]), Some(&states[1])],
                valve_requests: [Some(&requests[0]), Some(&requests[1])],
                readings: Some(readings),
                detections: detections.as_deref(),
                emergency_stop: engaged,
            })
            .clone();
        let open = [out.valve_commands[0], out.valve_commands[2]];
        let sealed = ArmId::ALL.map(|arm| vacuum.attachment(arm) == AttachmentState::Sealed);
        if engaged {
            assert!(!open[0] && !open[1], "valve open under the emergency stop");
        }
        for arm in 0..2 {
            let other = 1 - arm;
            let opened = open[arm] && !open_before[arm];
            assert!(
                !(opened && open_before[other] && open[other] && !sealed[other]),
                "valve opened beside an open unsealed one"
            );
        }
        both_open_unsealed = if open[0] && open[1] && !sealed[0] && !sealed[1] {
            both_open_unsealed + 1
        } else {
            0
        };
        assert!(both_open_unsealed <= 1, "both valves open unsealed for two periods");
        open_before = open;

        for arm in 0..2 {
            let target = bytes.payload::<ArmTarget>();
            let vacuum_state = bytes.payload::<VacuumState>();
            let grant = bytes.payload::<ValveGrant>();
            let other_state = bytes.payload::<ArmState>();
            let other_target = bytes.payload::<ArmTarget>();
            let feedback = EncoderSample {
                capture_ns: now_ns,
                position: std::array::from_fn(|_| bytes.f64()),
                velocity: std::array::from_fn(|_| bytes.f64()),
            };
            let input = ArmNodeInput {
                now_ns,
                feedback: Some(feedback),
                target: Some(&target),
                vacuum: Some(&vacuum_state),
                grant: Some(&grant),
                other_arm: Some(OtherArmInput { state: &other_state, target: Some(&other_target) }),
                emergency_stop: engaged,
            };
            match arms[arm].step(&input).servo {
                ServoOrder::Hold => {}
                ServoOrder::Track { position, velocity } => {
                    assert!(!engaged, "arm moves under the emergency stop");
                    let lo = params[arm].position_limits.min.to_array();
                    let hi = params[arm].position_limits.max.to_array();
                    for j in 0..4 {
                        assert!(position[j].is_finite() && (lo[j]..=hi[j]).contains(&position[j]));
                        assert!(velocity[j].is_finite());
                    }
                }
            }
        }
    }
});
