//! Any bytes as the stack channels the safety monitor judges (vacuum state, arm commands and
//! states, emergency stop), in any order and at any time steps: judged or refused with an error,
//! never a panic.
#![no_main]

use harvest_ipc::Payload;
use harvest_ipc::payloads::{ArmCommand, ArmState, EmergencyStop, VacuumState};
use harvest_monitor::StackMonitor;
use harvest_monitor::mapping::MappingConfig;
use harvest_monitor::stack_monitor::StackMessage;
use harvest_robot_model::ArmId;
use harvest_safety::safety_monitor::MonitorConfig;
use libfuzzer_sys::fuzz_target;

fn payload<T: Payload>(data: &[u8], at: &mut usize) -> Box<T> {
    let mut value = harvest_ipc::payload::boxed_zeroed::<T>();
    // SAFETY: `value` is a valid, uniquely borrowed `T` of `size_of::<T>()` bytes, and every bit
    // pattern is a valid `T` (the `Payload` contract).
    let raw = unsafe {
        std::slice::from_raw_parts_mut((&mut *value as *mut T).cast::<u8>(), std::mem::size_of::<T>())
    };
    for byte in raw.iter_mut() {
        *byte = data[*at % data.len()];
        *at += 1;
    }
    value
}

fuzz_target!(|data: &[u8]| {
    if data.is_empty() {
        return;
    }
    let mut monitor = StackMonitor::new(MappingConfig::default(), MonitorConfig::default());
    let mut t_ns = 0u64;
    let mut at = 0;
    let arms = [ArmId::Arm1, ArmId::Arm2];
    for &kind in data.iter().take(64) {
        t_ns = t_ns.saturating_add(u64::from(kind) * 1_000_000);
        let result = match kind % 6 {
            0 => monitor.feed(t_ns, StackMessage::Vacuum(&payload::<VacuumState>(data, &mut at))).map(|v| v.len()),
            1 | 2 => {
                let command = payload::<ArmCommand>(data, &mut at);
                monitor.feed(t_ns, StackMessage::Command(arms[usize::from(kind % 6 - 1)], &command)).map(|v| v.len())
            }
            3 | 4 => {
                let state = payload::<ArmState>(data, &mut at);
                monitor.feed(t_ns, StackMessage::State(arms[usize::from(kind % 6 - 3)], &state)).map(|v| v.len())
            }
            _ => monitor.feed(t_ns, StackMessage::Stop(&payload::<EmergencyStop>(data, &mut at))).map(|v| v.len()),
        };
        if let Err(error) = result {
            assert!(!error.to_string().is_empty());
        }
    }
    let _ = monitor.finish(t_ns).render();
});
