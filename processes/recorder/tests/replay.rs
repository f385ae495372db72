//! `replay` republishes a recording into another domain: subscribers there receive the
//! recorded messages, identical but for the transport's fresh `publish_ns`.

mod common;

use common::*;
use harvest_ipc::catalogue::{
    ARM_STATE, CAMERA_RGBD, EMERGENCY_STOP, PROCESS_HEALTH, VACUUM_STATE,
};
use harvest_ipc::payloads::RgbdFrame;
use harvest_ipc::{Context, Payload, Subscriber};
use harvest_rec::replay::{ReplayArgs, ReplayEnd, ReplayReport, run_replay_with};
use harvest_recording::payload_codec::zeroed_box;
use std::path::PathBuf;
use std::time::Duration;

fn record(arms: u32, frames: u32) -> (TempDir, PathBuf) {
    let dir = TempDir::new("replay");
    let domain = unique_domain("rsrc");
    let recorder = RunningRecorder::start(&domain, test_args(dir.path()));
    recorder.wait_ready();
    let context = Context::new(&domain, "publisher").expect("node");
    let mut publishers = TestPublishers::open(&context);
    publishers.send(arms, 3, frames);
    let report = recorder.stop().expect("recording");
    let file = report.files[0].clone();
    (dir, file)
}

fn subscribe<T: Payload>(context: &Context, channel: harvest_ipc::Channel<T>) -> Subscriber<T> {
    context
        .subscriber_with_buffer(channel, channel.spec.qos.subscriber_max_buffer_size)
        .expect("subscriber")
}

/// A replay on another thread (its own node) into `domain`, which keeps its channels open
/// until [`BackgroundReplay::finish`] (the samples of a closed publisher are gone).
struct BackgroundReplay {
    thread: std::thread::JoinHandle<ReplayReport>,
    release: std::sync::mpsc::Sender<()>,
}

impl BackgroundReplay {
    fn start(args: ReplayArgs, domain: &harvest_ipc::Domain) -> Self {
        let domain = domain.clone();
        let (release, released) = std::sync::mpsc::channel::<()>();
        let thread = std::thread::spawn(move || {
            run_replay_with(&args, &domain, |_| {
                let _ = released.recv();
            })
            .expect("replay")
        });
        Self { thread, release }
    }

    fn finish(self) -> ReplayReport {
        let _ = self.release.send(());
        self.thread.join().expect("replay thread")
    }
}

#[test]
fn replayed_messages_are_identical_to_the_recorded_ones() {
    let (_dir, file) = record(20, 2);
    let target = unique_domain("rdst");
    let context = Context::new(&target, "listener").expect("node");
    let arms = subscribe(&context, ARM_STATE[0]);
    let vacuum = subscribe(&context, VACUUM_STATE);
    let stop = subscribe(&context, EMERGENCY_STOP);
    let frames = subscribe(&context, CAMERA_RGBD);
    let health = subscribe(&context, PROCESS_HEALTH);

    let args = ReplayArgs {
        fast: true,
        ..ReplayArgs::for_files(vec![file.clone()])
    };
    let replay = BackgroundReplay::start(args, &target);
    let mut arm_states = Vec::new();
    let mut frame_count = 0u32;
    let (mut vacuum_count, mut stop_count) = (0, 0);
    wait_until("replayed messages", || {
        while let Some(state) = arms.receive().expect("receive") {
            arm_states.push(*state);
        }
        while let Some(frame) = frames.receive().expect("receive") {
            let mut expected = zeroed_box::<RgbdFrame>();
            fill_frame(&mut expected, frame_count);
            assert!(
                frame.rgb[..] == expected.rgb[..],
                "frame {frame_count} colour"
            );
            assert!(
                frame.depth_mm[..] == expected.depth_mm[..],
                "frame {frame_count} depth"
            );
            assert_eq!(frame.meta, expected.meta);
            assert_eq!(frame.header.capture_ns, 5_000 + u64::from(frame_count));
            frame_count += 1;
        }
        while vacuum.receive().expect("receive").is_some() {
            vacuum_count += 1;
        }
        while stop.receive().expect("receive").is_some() {
            stop_count += 1;
        }
        arm_states.len() == 20 && frame_count == 2 && vacuum_count == 3 && stop_count == 1
    });
    let report = replay.finish();
    assert_eq!(report.end, ReplayEnd::Finished);
    for (index, state) in arm_states.iter().enumerate() {
        let mut expected = arm_state(index as u32);
        expected.header.msg_seq = index as u64 + 1;
        expected.header.publish_ns = state.header.publish_ns;
        assert_eq!(*state, expected, "arm state {index}");
    }
    assert_eq!(report.published.get("arm1/state"), Some(&20));
    assert_eq!(report.published.get("camera/rgbd"), Some(&2));
    assert!(
        !report.published.contains_key("system/health"),
        "heartbeats are not replayed by default"
    );
    assert!(health.receive().expect("receive").is_none());
    assert!(report.skipped.is_empty(), "{:?}", report.skipped);
    assert!(
        report.mapped_views > 0,
        "the recording's mapped Foxglove channels are left out, not replayed"
    );
    println!("{report}");
}

#[test]
fn replay_selects_topics_and_a_time_window() {
    let (_dir, file) = record(30, 0);
    // The arm messages' recorded times, from the file itself.
    let mut arm_times = Vec::new();
    let mut first_ns = u64::MAX;
    harvest_recording::scan::scan_file(&file, Default::default(), |item| {
        if let harvest_recording::scan::ScanItem::Message(message) = item {
            first_ns = first_ns.min(message.log_time);
            if message.channel.topic == "arm1/state" {
                arm_times.push(message.log_time);
            }
        }
        std::ops::ControlFlow::Continue(())
    })
    .expect("scan");
    let from_ns = arm_times[10];
    let to_ns = arm_times[20];
    let target = unique_domain("rwin");
    let context = Context::new(&target, "listener").expect("node");
    let arms = subscribe(&context, ARM_STATE[0]);
    let vacuum = subscribe(&context, VACUUM_STATE);
    let args = ReplayArgs {
        include: vec!["arm*".into()],
        rate: 50.0,
        start_offset: Some(Duration::from_nanos(from_ns - first_ns)),
        duration: Some(Duration::from_nanos(to_ns - from_ns)),
        ..ReplayArgs::for_files(vec![file])
    };
    let replay = BackgroundReplay::start(args, &target);
    let mut received = Vec::new();
    wait_until("window replayed", || {
        while let Some(state) = arms.receive().expect("receive") {
            received.push(state.apple_id);
        }
        received.len() == 11
    });
    let report = replay.finish();
    assert_eq!(
        received,
        (1010..=1020).collect::<Vec<u32>>(),
        "messages 10..=20 of the recording"
    );
    assert_eq!(report.published.get("arm1/state"), Some(&11));
    assert!(
        vacuum.receive().expect("receive").is_none(),
        "vacuum/state excluded"
    );
}
