//! Property tests of the monitor's readers: the stack channels it judges,
//! fed payloads of any bit pattern in any order and at any time stamps, and recordings of such
//! payloads, cut or with bytes overwritten, through `harvest monitor --recording`. The monitor
//! judges or reports an error naming what was wrong; it never panics.
//!
//! Payloads are filled through their raw bytes (`Payload` makes every bit pattern a valid
//! value), so the properties hold whatever the field types of the payloads become.

use harvest_ipc::Payload;
use harvest_ipc::catalogue::{ARM_COMMAND, ARM_STATE, EMERGENCY_STOP, VACUUM_STATE};
use harvest_ipc::payloads::{ArmCommand, ArmState, EmergencyStop, VacuumState};
use harvest_monitor::StackMonitor;
use harvest_monitor::mapping::MappingConfig;
use harvest_monitor::recording::check_recording;
use harvest_monitor::stack_monitor::StackMessage;
use harvest_recording::schema::TopicInfo;
use harvest_recording::segment_writer::{ChunkCompression, ChunkSettings, SegmentWriter};
use harvest_robot_model::ArmId;
use harvest_safety::safety_monitor::MonitorConfig;
use proptest::prelude::*;
use std::io::Cursor;
use std::path::PathBuf;

/// Cases per property (each is a few hundred messages through the monitor, or one small file).
const CASES: u32 = 128;

const WILD: &[u64] = &[
    0x7ff8_0000_0000_0000, // NaN
    0x7ff0_0000_0000_0000, // +inf
    0xfff0_0000_0000_0000, // -inf
    0,
    1,
    2,
    3,
    5,
    255,
    u64::MAX,
    0x0101_0101_0101_0101, // every byte 1 (valves open, codes 1)
    0x0202_0202_0202_0202, // every byte 2 (sealed)
    0x7fc0_0000_4510_0000, // f32 2304, NaN
    0x3ff0_0000_0000_0000, // 1.0
];

fn wild_u64() -> impl Strategy<Value = u64> {
    prop_oneof![
        3 => prop::sample::select(WILD),
        1 => any::<u64>(),
    ]
}

/// A payload of type `T` made of `values` (8 bytes each, repeated).
fn payload<T: Payload>(values: &[u64]) -> Box<T> {
    let mut value = harvest_ipc::payload::boxed_zeroed::<T>();
    // SAFETY: `value` is a valid, uniquely borrowed `T` of `size_of::<T>()` bytes, and every bit
    // pattern is a valid `T` (the `Payload` contract), so any bytes written leave a valid `T`.
    let bytes = unsafe {
        std::slice::from_raw_parts_mut(
            (&mut *value as *mut T).cast::<u8>(),
            std::mem::size_of::<T>(),
        )
    };
    if !values.is_empty() {
        for (chunk, v) in bytes.chunks_mut(8).zip(values.iter().cycle()) {
            chunk.copy_from_slice(&v.to_le_bytes()[..chunk.len()]);
        }
    }
    value
}

/// One monitored message: which channel (0 vacuum, 1-2 commands, 3-4 states, 5 stop), the
/// time step before it, and its bytes.
fn message() -> impl Strategy<Value = (u8, u64, Vec<u64>)> {
    (
        0u8..6,
        prop_oneof![Just(0u64), 1u64..20_000_000, Just(u64::MAX / 2)],
        prop::collection::vec(wild_u64(), 0..12),
    )
}

const ARMS: [ArmId; 2] = [ArmId::Arm1, ArmId::Arm2];

/// A scratch directory removed on drop.
struct TempDir(PathBuf);

impl TempDir {
    fn new() -> Self {
        use std::sync::atomic::{AtomicU64, Ordering};
        static NEXT: AtomicU64 = AtomicU64::new(0);
        let path = std::env::temp_dir().join(format!(
            "harvest-monitor-prop-{}-{}",
            std::process::id(),
            NEXT.fetch_add(1, Ordering::Relaxed)
        ));
        std::fs::create_dir_all(&path).expect("temp dir");
        Self(path)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// A finished recording of `messages` on the monitored channels.
fn recording(messages: &[(u8, u64, Vec<u64>)]) -> Vec<u8> {
    let topics = [
        TopicInfo::of(VACUUM_STATE),
        TopicInfo::of(ARM_COMMAND[0]),
        TopicInfo::of(ARM_COMMAND[1]),
        TopicInfo::of(ARM_STATE[0]),
        TopicInfo::of(ARM_STATE[1]),
        TopicInfo::of(EMERGENCY_STOP),
    ];
    let settings = ChunkSettings {
        compression: ChunkCompression::None,
        compression_level: 0,
        compression_threads: 0,
        chunk_size_bytes: 512,
    };
    let mut writer =
        SegmentWriter::new(Cursor::new(Vec::new()), &settings, topics.len()).expect("writer");
    let mut t_ns = 1_000_000_000u64;
    for (n, (channel, dt_ns, values)) in messages.iter().enumerate() {
        t_ns = t_ns.saturating_add(*dt_ns);
        let mut data = Vec::new();
        match channel {
            0 => payload::<VacuumState>(values).encode(&mut data),
            1 | 2 => payload::<ArmCommand>(values).encode(&mut data),
            3 | 4 => payload::<ArmState>(values).encode(&mut data),
            _ => payload::<EmergencyStop>(values).encode(&mut data),
        }
        .expect("encode");
        let index = usize::from(*channel);
        writer
            .write_message(index, &topics[index], n as u32, t_ns, t_ns, &data)
            .expect("message");
    }
    writer.finish().expect("finish").into_inner()
}

/// Feeds one message; the violations it revealed, or the monitor's error.
fn feed(
    monitor: &mut StackMonitor,
    t_ns: u64,
    channel: u8,
    values: &[u64],
) -> Result<Vec<String>, String> {
    let result = match channel {
        0 => monitor.feed(t_ns, StackMessage::Vacuum(&payload::<VacuumState>(values))),
        1 | 2 => {
            let arm = ARMS[usize::from(channel - 1)];
            let command = payload::<ArmCommand>(values);
            monitor.feed(t_ns, StackMessage::Command(arm, &command))
        }
        3 | 4 => {
            let arm = ARMS[usize::from(channel - 3)];
            let state = payload::<ArmState>(values);
            monitor.feed(t_ns, StackMessage::State(arm, &state))
        }
        _ => monitor.feed(t_ns, StackMessage::Stop(&payload::<EmergencyStop>(values))),
    };
    result
        .map(|violations| violations.iter().map(ToString::to_string).collect())
        .map_err(|error| error.to_string())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(CASES))]

    /// Any sequence of payloads of any bit pattern, at any time steps.
    #[test]
    fn the_monitor_judges_any_payloads(messages in prop::collection::vec(message(), 0..300)) {
        let mut monitor = StackMonitor::new(MappingConfig::default(), MonitorConfig::default());
        let mut t_ns = 0u64;
        for (channel, dt_ns, values) in &messages {
            t_ns = t_ns.saturating_add(*dt_ns);
            match feed(&mut monitor, t_ns, *channel, values) {
                Ok(violations) => prop_assert!(violations.iter().all(|v| !v.is_empty())),
                Err(error) => prop_assert!(!error.is_empty()),
            }
        }
        let report = monitor.finish(t_ns);
        let _ = report.render();
    }

    /// Recordings of such payloads, whole, cut, or with bytes overwritten.
    #[test]
    fn monitoring_any_recording_never_panics(
        messages in prop::collection::vec(message(), 1..80),
        cut_fraction in prop_oneof![Just(1.0f64), 0.0f64..1.0],
        edits in prop::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 0..6),
    ) {
        let dir = TempDir::new();
        let mut bytes = recording(&messages);
        for (at, value) in &edits {
            let at = at.index(bytes.len());
            bytes[at] = *value;
        }
        bytes.truncate((bytes.len() as f64 * cut_fraction) as usize);
        let path = dir.0.join("input.mcap");
        std::fs::write(&path, &bytes).expect("write");
        match check_recording(&path, MappingConfig::default(), MonitorConfig::default(), |_| {}) {
            Ok(report) => {
                let _ = report.render();
            }
            Err(error) => prop_assert!(error.to_string().contains("input.mcap"), "{error}"),
        }
    }
}
