//! Property test of `harvest replay`'s reading side: recordings holding
//! payloads of any bit pattern, cut anywhere or with bytes overwritten, replayed (as fast as
//! possible) into real iceoryx2 channels: every message is decoded into loaned shared memory and
//! published, or skipped and counted; an unreadable file is refused with an error naming it.
//! Never a panic.

use harvest_ipc::catalogue::{
    ARM_COMMAND, ARM_STATE, EMERGENCY_STOP, PERCEPTION_APPLES, VACUUM_STATE,
};
use harvest_ipc::payloads::{AppleDetections, ArmCommand, ArmState, EmergencyStop, VacuumState};
use harvest_ipc::{Payload, ScratchDomain};
use harvest_rec::replay::{ReplayArgs, run_replay_with};
use harvest_recording::schema::TopicInfo;
use harvest_recording::segment_writer::{ChunkCompression, ChunkSettings, SegmentWriter};
use proptest::prelude::*;
use std::io::Cursor;
use std::path::PathBuf;
use std::time::Duration;

/// Cases: each opens a replay node and its publishers in shared memory.
const CASES: u32 = 24;

const WILD: &[u64] = &[
    0x7ff8_0000_0000_0000, // NaN
    0x7ff0_0000_0000_0000, // +inf
    0,
    1,
    2,
    255,
    u64::MAX,
    0x3ff0_0000_0000_0000, // 1.0
];

fn wild_u64() -> impl Strategy<Value = u64> {
    prop_oneof![
        3 => prop::sample::select(WILD),
        1 => any::<u64>(),
    ]
}

/// A payload of type `T` made of `values` (8 bytes each, repeated), encoded.
fn encoded<T: Payload>(values: &[u64]) -> Vec<u8> {
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
    let mut out = Vec::new();
    value.encode(&mut out).expect("encode");
    out
}

/// A finished recording: `messages` of (channel index, payload bytes) 5 ms apart.
fn recording(messages: &[(usize, Vec<u64>)]) -> Vec<u8> {
    let topics = [
        TopicInfo::of(VACUUM_STATE),
        TopicInfo::of(ARM_STATE[0]),
        TopicInfo::of(ARM_COMMAND[0]),
        TopicInfo::of(EMERGENCY_STOP),
        TopicInfo::of(PERCEPTION_APPLES),
    ];
    let settings = ChunkSettings {
        compression: ChunkCompression::Lz4,
        compression_level: 0,
        compression_threads: 0,
        chunk_size_bytes: 400,
    };
    let mut writer =
        SegmentWriter::new(Cursor::new(Vec::new()), &settings, topics.len()).expect("writer");
    for (n, (index, values)) in messages.iter().enumerate() {
        let data = match index {
            0 => encoded::<VacuumState>(values),
            1 => encoded::<ArmState>(values),
            2 => encoded::<ArmCommand>(values),
            3 => encoded::<EmergencyStop>(values),
            _ => encoded::<AppleDetections>(values),
        };
        let t_ns = 1_000_000_000 + n as u64 * 5_000_000;
        writer
            .write_message(*index, &topics[*index], n as u32, t_ns, t_ns, &data)
            .expect("message");
    }
    writer.finish().expect("finish").into_inner()
}

fn scratch_file() -> PathBuf {
    use std::sync::atomic::{AtomicU64, Ordering};
    static NEXT: AtomicU64 = AtomicU64::new(0);
    std::env::temp_dir().join(format!(
        "harvest-replay-prop-{}-{}.mcap",
        std::process::id(),
        NEXT.fetch_add(1, Ordering::Relaxed)
    ))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(CASES))]

    #[test]
    fn replaying_any_recording_never_panics(
        messages in prop::collection::vec((0usize..5, prop::collection::vec(wild_u64(), 0..10)), 1..40),
        cut_fraction in prop_oneof![Just(1.0f64), 0.0f64..1.0],
        edits in prop::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 0..6),
    ) {
        let mut bytes = recording(&messages);
        for (at, value) in &edits {
            let at = at.index(bytes.len());
            bytes[at] = *value;
        }
        bytes.truncate((bytes.len() as f64 * cut_fraction) as usize);
        let path = scratch_file();
        std::fs::write(&path, &bytes).expect("write");
        let mut args = ReplayArgs::for_files(vec![path.clone()]);
        args.fast = true;
        args.linger = Duration::ZERO;
        // A domain per case: the replay closes its node and ports when done, and the domain
        // leaves nothing in /dev/shm when dropped.
        let domain = ScratchDomain::new("rprop");
        let outcome = run_replay_with(&args, &domain, |_| {});
        let _ = std::fs::remove_file(&path);
        match outcome {
            Ok(report) => {
                let _ = report.to_string();
                prop_assert!(report.messages() <= messages.len() as u64);
            }
            Err(error) => prop_assert!(!error.to_string().is_empty()),
        }
    }
}
