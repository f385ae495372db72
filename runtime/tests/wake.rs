//! The runtime's two wake-ups and its in-place slots over real iceoryx2 shared memory: a
//! camera double as a `Source` node paced by its device (`Wake::Device`), writing 6.8 MB
//! frames into loaned `camera/rgbd` samples, and a node woken by each frame's event
//! (`Wake::Input`) that reads the frame in place and writes a loaned `perception/apples`
//! sample. Each runs on its own thread with its own iceoryx2 node, as two processes would.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use harvest_hw::rgbd_camera::RgbdCamera;
use harvest_hw::{DeviceError, ErrorKind};
use harvest_ipc::catalogue::{CAMERA_RGBD, PERCEPTION_APPLES, PROCESS_HEALTH};
use harvest_ipc::payloads::rgbd_frame::RGB_BYTES;
use harvest_ipc::payloads::{AppleDetections, ProcessHealth, RgbdFrame};
use harvest_ipc::{Context, MonotonicClock, Payload, ScratchDomain, Subscriber};
use harvest_node::{
    InputVisitor, Inputs, LatestInPlace, Loaned, Node, NodeTick, OutputVisitor, Outputs, Source,
};
use harvest_runtime::{Wake, WakeOptions, run_on_wake};

/// Watchdog on every wait of the test.
const WATCHDOG: Duration = Duration::from_secs(60);

#[derive(Debug, thiserror::Error)]
#[error("camera double lost")]
struct Lost;

impl DeviceError for Lost {
    fn kind(&self) -> ErrorKind {
        ErrorKind::Disconnected
    }
}

/// A camera that delivers a frame whenever the test fires a shot (the frame's first and last
/// colour bytes carry the shot's value); it blocks on the shots as a driver on its device.
struct ShotCamera {
    shots: mpsc::Receiver<u8>,
}

impl RgbdCamera for ShotCamera {
    type Error = Lost;

    fn capture_into(&mut self, frame: &mut RgbdFrame, timeout: Duration) -> Result<bool, Lost> {
        match self.shots.recv_timeout(timeout) {
            Ok(value) => {
                frame.header.capture_ns = MonotonicClock::read_ns();
                frame.rgb[0] = value;
                frame.rgb[RGB_BYTES - 1] = value;
                Ok(true)
            }
            Err(mpsc::RecvTimeoutError::Timeout) => Ok(false),
            Err(mpsc::RecvTimeoutError::Disconnected) => Err(Lost),
        }
    }
}

#[derive(Default)]
struct FrameIn {
    frames: LatestInPlace<RgbdFrame>,
}

impl Inputs for FrameIn {
    fn visit<V: InputVisitor>(&mut self, v: &mut V) -> Result<(), V::Error> {
        v.latest_in_place(CAMERA_RGBD, &mut self.frames)
    }
}

#[derive(Default)]
struct DetectionsOut {
    detections: Loaned<AppleDetections>,
}

impl Outputs for DetectionsOut {
    fn visit<V: OutputVisitor>(&mut self, v: &mut V) -> Result<(), V::Error> {
        v.loaned(PERCEPTION_APPLES, &mut self.detections)
    }
}

/// Answers each frame with a detections message naming it, the sum of its two marked bytes
/// in `processing_ns` (read in place at both ends of the 6 MB image).
struct Inspector;

impl Node for Inspector {
    type Inputs = FrameIn;
    type Outputs = DetectionsOut;
    type Devices = ();
    type Error = std::convert::Infallible;

    fn name(&self) -> &str {
        "inspector"
    }

    fn inputs(&self) -> FrameIn {
        FrameIn::default()
    }

    fn outputs(&self) -> DetectionsOut {
        DetectionsOut::default()
    }

    fn step(
        &mut self,
        _tick: &NodeTick,
        _readings: Option<&()>,
        inputs: &FrameIn,
        _commands: &mut (),
        outputs: &mut DetectionsOut,
    ) -> Result<(), Self::Error> {
        let (Some(frame), Some(out)) = (inputs.frames.fresh(), outputs.detections.sample_mut())
        else {
            return Ok(());
        };
        out.header.capture_ns = frame.header.capture_ns;
        out.source_frame_seq = frame.header.msg_seq;
        out.source_capture_ns = frame.header.capture_ns;
        out.processing_ns = u64::from(frame.rgb[0]) + u64::from(frame.rgb[RGB_BYTES - 1]);
        out.apples.clear();
        outputs.detections.send();
        Ok(())
    }
}

fn options(wake: Wake, stop: &AtomicBool) -> WakeOptions<'_> {
    WakeOptions {
        stop: Some(stop),
        ..WakeOptions::sensor(wake, 1)
    }
}

/// Waits (event-driven, bounded by the watchdog) for the first message `accept` takes.
fn wait_for<T: Payload + Copy>(subscriber: &Subscriber<T>, accept: impl Fn(&T) -> bool) -> T {
    let deadline = Instant::now() + WATCHDOG;
    loop {
        while let Some(message) = subscriber.receive().expect("receive") {
            if accept(&message) {
                return *message;
            }
        }
        let remaining = deadline.saturating_duration_since(Instant::now());
        assert!(!remaining.is_zero(), "watchdog: {:?}", subscriber.channel());
        let _ = subscriber.listener().timed_wait(|_| {}, remaining);
    }
}

#[test]
fn a_device_paced_source_and_an_event_woken_node_exchange_frames_in_place() {
    let domain = ScratchDomain::new("wake");
    let stop = Arc::new(AtomicBool::new(false));
    let (shots, shots_rx) = mpsc::channel();
    let camera = {
        let (domain, stop) = (domain.clone(), Arc::clone(&stop));
        std::thread::spawn(move || {
            let context = Context::new(&domain, "camera").expect("context");
            let source = Source::new(
                "camera",
                CAMERA_RGBD,
                ShotCamera { shots: shots_rx },
                Duration::from_millis(50),
                3,
            );
            let finished =
                run_on_wake(&context, source, (), options(Wake::Device, &stop)).expect("run");
            let sent = finished.runner.node().counts().sent;
            finished.result.map(|_| sent).map_err(|e| e.to_string())
        })
    };
    let inspector = {
        let (domain, stop) = (domain.clone(), Arc::clone(&stop));
        std::thread::spawn(move || {
            let context = Context::new(&domain, "inspector").expect("context");
            let wake = Wake::Input {
                topic: CAMERA_RGBD.spec.topic,
            };
            let finished = run_on_wake(&context, Inspector, (), options(wake, &stop)).expect("run");
            finished.result.map_err(|e| e.to_string())
        })
    };

    let context = Context::new(&domain, "test").expect("context");
    let health = context.subscriber(PROCESS_HEALTH).expect("health");
    let detections = context.subscriber(PERCEPTION_APPLES).expect("detections");
    // Both loops run (their ports exist) once each has sent a heartbeat.
    let mut running = Vec::new();
    while running.len() < 2 {
        let beat: ProcessHealth = wait_for(&health, |_| true);
        let name = beat.process_name.as_str().to_owned();
        if !running.contains(&name) {
            running.push(name);
        }
    }

    // One shot at a time: each frame is answered before the next is taken.
    for value in 1..=5u8 {
        shots.send(value).expect("shot");
        let answer = wait_for(&detections, |out| out.source_frame_seq == u64::from(value));
        assert_eq!(answer.processing_ns, 2 * u64::from(value), "{answer:?}");
        assert_eq!(answer.source_capture_ns, answer.header.capture_ns);
    }

    stop.store(true, Ordering::SeqCst);
    assert_eq!(camera.join().expect("camera thread"), Ok(5));
    let ticks = inspector
        .join()
        .expect("inspector thread")
        .expect("run ends cleanly");
    // Woken by the frames (a wake-up may find its frame already taken), not by a clock.
    assert!((5..=10).contains(&ticks), "{ticks} ticks");
}
