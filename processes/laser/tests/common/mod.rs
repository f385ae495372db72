//! Helpers of the ALACS-over-IPC tests: unique domains and the simulator's ALACS device served
//! on its own thread with its own node, exactly as the sim process serves it.

#![allow(dead_code)]

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc;
use std::thread::JoinHandle;

use harvest_laser_process::process::{LaserArgs, run_until};
use std::time::{Duration, Instant};

use harvest_ipc::catalogue::{HW_ALACS_COMMAND, HW_ALACS_IMAGE};
use harvest_ipc::{Context, Domain, Flow, Payload, Subscriber, Waiter};
use harvest_sim::alacs_device::{AlacsDeviceConfig, AlacsDeviceServer};
use harvest_sim::{Scenario, World};

/// A domain no other test (or concurrent run) uses; what it leaves in /dev/shm is removed when
/// it is dropped.
pub fn unique_domain(tag: &str) -> harvest_ipc::ScratchDomain {
    harvest_ipc::ScratchDomain::new(tag)
}

/// Watchdog on every wait of the tests.
pub const WATCHDOG: Duration = Duration::from_secs(60);

/// Waits (event-driven, bounded by the watchdog) for the first message `accept` takes.
pub fn wait_for<T: Payload + Copy>(subscriber: &Subscriber<T>, accept: impl Fn(&T) -> bool) -> T {
    let deadline = Instant::now() + WATCHDOG;
    loop {
        while let Some(message) = subscriber.receive().expect("receive") {
            if accept(&message) {
                return *message;
            }
        }
        let remaining = deadline.saturating_duration_since(Instant::now());
        assert!(
            !remaining.is_zero(),
            "watchdog: nothing on {:?}",
            subscriber.channel()
        );
        let _ = subscriber.listener().timed_wait(|_| {}, remaining);
    }
}

/// The world the device shows: the `ideal` scenario (a grid of apples, no leaves), seed 5.
pub fn ideal_world() -> World {
    World::generate(&Scenario::preset("ideal").expect("preset"), 5).expect("world")
}

/// The simulator's ALACS device on its own thread; stops on drop.
pub struct Device {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<Result<u64, String>>>,
}

impl Device {
    /// Starts serving [`ideal_world`] in `domain` and returns once its ports exist.
    pub fn start(domain: &Domain) -> Self {
        Self::start_slow(domain, Duration::ZERO)
    }

    /// [`Self::start`] with a device that takes `delay` more for every answer (a slow slide
    /// or camera).
    pub fn start_slow(domain: &Domain, delay: Duration) -> Self {
        let stop = Arc::new(AtomicBool::new(false));
        let (ready_tx, ready_rx) = mpsc::channel();
        let thread = {
            let (domain, stop) = (domain.clone(), Arc::clone(&stop));
            std::thread::spawn(move || serve(&domain, &stop, &ready_tx, delay))
        };
        ready_rx
            .recv_timeout(Duration::from_secs(30))
            .expect("device thread ready");
        Self {
            stop,
            thread: Some(thread),
        }
    }

    /// Stops the device and returns the number of commands it answered.
    pub fn finish(mut self) -> u64 {
        self.stop.store(true, Ordering::SeqCst);
        let thread = self.thread.take().expect("running");
        thread.join().expect("device thread").expect("device loop")
    }
}

impl Drop for Device {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
    }
}

/// What the sim process does for the ALACS: answer every command with one loaned image, each
/// `delay` late.
fn serve(
    domain: &Domain,
    stop: &AtomicBool,
    ready: &mpsc::Sender<()>,
    delay: Duration,
) -> Result<u64, String> {
    let world = ideal_world();
    let mut server =
        AlacsDeviceServer::new(AlacsDeviceConfig::default()).map_err(|e| e.to_string())?;
    let context = Context::new(domain, "sim_alacs").map_err(|e| e.to_string())?;
    let commands = context
        .subscriber(HW_ALACS_COMMAND)
        .map_err(|e| e.to_string())?;
    let mut images = context
        .publisher(HW_ALACS_IMAGE)
        .map_err(|e| e.to_string())?;
    let waiter = Waiter::new().map_err(|e| e.to_string())?;
    let command_guard = waiter
        .attach_listener(commands.listener())
        .map_err(|e| e.to_string())?;
    let stop_check = waiter
        .attach_interval(Duration::from_millis(20))
        .map_err(|e| e.to_string())?;
    ready.send(()).map_err(|e| e.to_string())?;
    let mut answered = 0;
    waiter
        .run(|attachment| -> Result<Flow, String> {
            if attachment.has_event_from(&command_guard) {
                while let Some(command) = commands.receive().map_err(|e| e.to_string())? {
                    if !delay.is_zero() {
                        // The test double of a slow device.
                        std::thread::sleep(delay);
                    }
                    let mut image = images.loan().map_err(|e| e.to_string())?;
                    server.handle(&world, &command, &mut image);
                    images.send(image).map_err(|e| e.to_string())?;
                    answered += 1;
                }
            }
            if attachment.has_event_from(&stop_check) && stop.load(Ordering::SeqCst) {
                return Ok(Flow::Stop);
            }
            Ok(Flow::Continue)
        })
        .map_err(|e| e.to_string())?;
    Ok(answered)
}

/// The laser loop on its own thread.
pub struct Laser {
    stop: Arc<AtomicBool>,
    thread: JoinHandle<Result<(), String>>,
}

impl Laser {
    pub fn start(domain: &Domain) -> Self {
        let stop = Arc::new(AtomicBool::new(false));
        let thread = {
            let (domain, stop) = (domain.clone(), Arc::clone(&stop));
            std::thread::spawn(move || {
                let args = LaserArgs {
                    calibration: Some(
                        concat!(
                            env!("CARGO_MANIFEST_DIR"),
                            "/../../sim/alacs_calibration.toml"
                        )
                        .into(),
                    ),
                    device_timeout_ms: 2900,
                };
                run_until(&args, &domain, "laser", &stop).map_err(|e| e.to_string())
            })
        };
        Self { stop, thread }
    }

    pub fn finish(self) {
        self.stop.store(true, Ordering::SeqCst);
        self.thread
            .join()
            .expect("laser thread")
            .expect("laser loop ends cleanly");
    }
}
