//! The simulator's physics thread keeps serving the servos while a camera frame is being
//! rendered: with a camera renderer that holds its frame until the test releases it, the
//! physics steps and the encoder feedback go on. Counts ticks and samples; no timing is
//! asserted (the bounded waits only keep a broken build from hanging).

use harvest_ipc::catalogue::HW_ARM_ENCODERS;
use harvest_ipc::payloads::RgbdFrame;
use harvest_ipc::{Context, MonotonicClock, Payload, ScratchDomain};
use harvest_sim::World;
use harvest_sim::process::{SimError, SimThreadsConfig, run_threads};
use harvest_sim::render_rgbd::RenderError;
use harvest_sim::render_thread::{CameraRenderer, RenderThreadError};
use harvest_sim::robot::SimRobot;
use harvest_sim::scenario::Scenario;
use harvest_sim::thread_link::ThreadLink;
use std::sync::mpsc::{Receiver, Sender, channel};
use std::time::{Duration, Instant};

/// Longest wait for anything in these tests (a hang guard, not a performance bound).
const WATCHDOG: Duration = Duration::from_secs(60);
/// Physics steps that must happen while the renderer holds its frame.
const STEPS_DURING_RENDER: u64 = 20;

/// A camera that, on its first frame, reports that it holds the frame and waits for the
/// release; later frames return at once.
struct HeldCamera {
    holding: Sender<()>,
    release: Receiver<()>,
    frames: u64,
}

impl CameraRenderer for HeldCamera {
    fn render(&mut self, _: &World, _: u64, _: &mut RgbdFrame) -> Result<(), RenderError> {
        self.frames += 1;
        if self.frames == 1 {
            let _ = self.holding.send(());
            // A dropped sender (the test ended) releases the frame too.
            let _ = self.release.recv();
        }
        Ok(())
    }
}

/// A camera whose renderer fails on its first frame.
struct FailingCamera;

impl CameraRenderer for FailingCamera {
    fn render(&mut self, _: &World, _: u64, frame: &mut RgbdFrame) -> Result<(), RenderError> {
        Err(RenderError::BufferSize {
            buffer: "rgb",
            expected: frame.rgb.len() + 1,
            actual: frame.rgb.len(),
            width: 1,
            height: 1,
        })
    }
}

fn robot() -> SimRobot {
    SimRobot::new(&Scenario::preset("ideal").expect("ideal"), 1).expect("robot")
}

fn wait_until(what: &str, mut done: impl FnMut() -> bool) {
    let started = Instant::now();
    while !done() {
        assert!(started.elapsed() < WATCHDOG, "gave up waiting: {what}");
        std::thread::sleep(Duration::from_millis(1));
    }
}

#[test]
fn physics_steps_and_encoders_go_on_while_a_frame_is_rendered() {
    let domain = ScratchDomain::new("simrender");
    let config = SimThreadsConfig::new("sim", Duration::from_millis(20), false);
    let robot = robot();
    let link = ThreadLink::new(robot.world());
    let probe = Context::new(&domain, "probe").expect("probe node");
    let encoders = probe
        .subscriber_with_buffer(HW_ARM_ENCODERS[0], 256)
        .expect("encoder subscriber");
    let (holding_tx, holding) = channel();
    let (release, release_rx) = channel();
    let mut camera = HeldCamera {
        holding: holding_tx,
        release: release_rx,
        frames: 0,
    };
    let (ticks_during_render, samples_during_render, frames, result) =
        std::thread::scope(|scope| {
            let sim = scope.spawn(|| {
                let result = run_threads(&domain, &config, robot, &mut camera, &link);
                (result, camera.frames)
            });
            // Stop the simulator whatever happens below (a failed assertion included).
            let _stop = link.stop_on_drop();
            holding
                .recv_timeout(WATCHDOG)
                .expect("the renderer got its first frame");
            let held_since_ns = MonotonicClock::read_ns();
            let ticks_at_hold = link.physics_ticks();
            wait_until("physics steps while the frame is held", || {
                link.physics_ticks() >= ticks_at_hold + STEPS_DURING_RENDER
            });
            let ticks_during_render = link.physics_ticks() - ticks_at_hold;
            let mut samples_during_render = 0u64;
            while let Some(sample) = encoders.receive().expect("receive") {
                if sample.header().publish_ns > held_since_ns {
                    samples_during_render += 1;
                }
            }
            release.send(()).expect("release the frame");
            link.request_stop();
            let (result, frames) = sim.join().expect("simulator thread");
            (ticks_during_render, samples_during_render, frames, result)
        });
    result.expect("both threads stop cleanly on request");
    assert!(ticks_during_render >= STEPS_DURING_RENDER);
    // One encoder sample per step: the feedback was served during the render, not after it.
    assert!(
        samples_during_render >= STEPS_DURING_RENDER,
        "{samples_during_render} encoder samples while the frame was held"
    );
    assert!(frames >= 1);
}

#[test]
fn a_render_failure_stops_the_physics_thread_and_is_reported() {
    let domain = ScratchDomain::new("simfail");
    let config = SimThreadsConfig::new("sim", Duration::from_millis(20), false);
    let robot = robot();
    let link = ThreadLink::new(robot.world());
    let error = run_threads(&domain, &config, robot, &mut FailingCamera, &link)
        .expect_err("the render failure ends the simulator");
    assert!(
        matches!(
            error,
            SimError::RenderThread(RenderThreadError::Camera { frame_seq: 1, .. })
        ),
        "{error}"
    );
    assert!(
        error
            .to_string()
            .starts_with("sim render thread: camera frame 1")
    );
    assert!(link.stop_requested());
}
