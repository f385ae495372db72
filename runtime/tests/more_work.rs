//! `Wake::Input` with a node that has more work (`Node::has_more_work`): woken by one request,
//! it is ticked back to back until the work is done, without another sample and without a
//! clock, and the heartbeat goes out between the ticks. The node runs on its own thread with
//! its own iceoryx2 node, as a process would; each unit of work takes 100 ms (a test double
//! of one device exchange).

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use harvest_ipc::catalogue::{LASER_SCAN_REQUEST, LASER_SCAN_RESULT, PROCESS_HEALTH};
use harvest_ipc::payloads::{LaserScanRequest, LaserScanResult, ProcessHealth, ProcessRunState};
use harvest_ipc::{Context, MonotonicClock, Payload, ScratchDomain, Subscriber};
use harvest_node::ports::{Drain, Out};
use harvest_node::{InputVisitor, Inputs, Node, NodeHealth, NodeTick, OutputVisitor, Outputs};
use harvest_runtime::{Wake, WakeOptions, run_on_wake};

/// Watchdog on every wait of the test.
const WATCHDOG: Duration = Duration::from_secs(60);

/// One unit of work.
const UNIT: Duration = Duration::from_millis(100);

#[derive(Default)]
struct Requests {
    requests: Drain<LaserScanRequest>,
}

impl Inputs for Requests {
    fn visit<V: InputVisitor>(&mut self, v: &mut V) -> Result<(), V::Error> {
        v.drain(LASER_SCAN_REQUEST, &mut self.requests)
    }
}

#[derive(Default)]
struct Results {
    results: Out<LaserScanResult>,
}

impl Outputs for Results {
    fn visit<V: OutputVisitor>(&mut self, v: &mut V) -> Result<(), V::Error> {
        v.output(LASER_SCAN_RESULT, &mut self.results)
    }
}

/// Each request asks for `request_seq` units of work, one per tick; the answer says how many
/// ticks the node had run by then (`candidate_count`).
#[derive(Default)]
struct Worker {
    left: u32,
    request_seq: u32,
    ticks: u64,
}

impl Node for Worker {
    type Inputs = Requests;
    type Outputs = Results;
    type Devices = ();
    type Error = std::convert::Infallible;

    fn name(&self) -> &str {
        "worker"
    }

    fn inputs(&self) -> Requests {
        Requests::default()
    }

    fn outputs(&self) -> Results {
        Results::default()
    }

    fn has_more_work(&self) -> bool {
        self.left > 0
    }

    fn health(&mut self) -> Option<NodeHealth> {
        Some(NodeHealth {
            state: ProcessRunState::Running,
            detail: "work_left",
            value: u64::from(self.left),
            device_error: None,
        })
    }

    fn step(
        &mut self,
        _tick: &NodeTick,
        _readings: Option<&()>,
        inputs: &Requests,
        _commands: &mut (),
        outputs: &mut Results,
    ) -> Result<(), Self::Error> {
        self.ticks += 1;
        for request in inputs.requests.items() {
            self.left += request.request_seq;
            self.request_seq = request.request_seq;
        }
        if self.left > 0 {
            std::thread::sleep(UNIT);
            self.left -= 1;
            if self.left == 0 {
                outputs.results.send(LaserScanResult {
                    request_seq: self.request_seq,
                    candidate_count: self.ticks as u8,
                    ..LaserScanResult::default()
                });
            }
        }
        Ok(())
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

fn is_worker(beat: &ProcessHealth) -> bool {
    beat.process_name.as_str() == "worker"
}

#[test]
fn a_node_with_more_work_is_ticked_back_to_back_with_heartbeats_between() {
    let domain = ScratchDomain::new("morework");
    let stop = Arc::new(AtomicBool::new(false));
    let worker = {
        let (domain, stop) = (domain.clone(), Arc::clone(&stop));
        std::thread::spawn(move || {
            let context = Context::new(&domain, "worker").expect("context");
            let options = WakeOptions {
                stop: Some(&stop),
                ..WakeOptions::sensor(
                    Wake::Input {
                        topic: LASER_SCAN_REQUEST.spec.topic,
                    },
                    1,
                )
            };
            let finished = run_on_wake(&context, Worker::default(), (), options).expect("run");
            finished.result.map_err(|e| e.to_string())
        })
    };

    let context = Context::new(&domain, "test").expect("context");
    let health = context.subscriber(PROCESS_HEALTH).expect("health");
    let mut requests = context.publisher(LASER_SCAN_REQUEST).expect("requests");
    let results = context.subscriber(LASER_SCAN_RESULT).expect("results");
    wait_for(&health, is_worker);

    // 15 units of 100 ms on one request.
    let sent_ns = MonotonicClock::read_ns();
    requests
        .publish(&LaserScanRequest {
            request_seq: 15,
            ..LaserScanRequest::default()
        })
        .expect("request");
    let result = wait_for(&results, |r| r.request_seq == 15);
    let took_ns = result.header.publish_ns - sent_ns;
    assert!(
        took_ns >= 15 * UNIT.as_nanos() as u64,
        "{took_ns} ns for 15 units"
    );
    // Every unit in its own tick after one wake-up: the first tick and 14 more back to back
    // (one tick more if a wake-up came before the request).
    assert!((15..=16).contains(&result.candidate_count), "{result:?}");

    // The heartbeat went out between the ticks: beats sent while work was left.
    let mut during_work = 0;
    while let Some(beat) = health.receive().expect("receive") {
        let beat = *beat;
        if is_worker(&beat)
            && beat.detail.as_str() == "work_left"
            && beat.detail_value > 0
            && beat.header.publish_ns > sent_ns
        {
            during_work += 1;
        }
    }
    assert!(
        during_work >= 2,
        "{during_work} heartbeats during 1.5 s of work"
    );

    stop.store(true, Ordering::SeqCst);
    let ticks = worker
        .join()
        .expect("worker thread")
        .expect("run ends cleanly");
    assert!((15..=17).contains(&ticks), "{ticks} ticks");
}
