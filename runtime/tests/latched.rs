//! A latched channel's late joiner gets the last value at the writer's next tick, not at its
//! next change: the runtime connects new subscribers after every tick of a node writing a
//! [`Qos::STATE`] channel. Without that, a reader that starts after the executive engaged the
//! stop (a console, a bridge, a restarted arm) would see no stop until the stop changes.
//! Real iceoryx2 shared memory; the writer runs on its own thread with its own node.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use harvest_ipc::catalogue::{Channel, Qos};
use harvest_ipc::payloads::EmergencyStop;
use harvest_ipc::{Context, ScratchDomain, Subscriber};
use harvest_node::{Drain, InputVisitor, Inputs, Node, NodeTick, Out, OutputVisitor, Outputs};
use harvest_runtime::{Wake, WakeOptions, run_on_wake};

const WATCHDOG: Duration = Duration::from_secs(30);
/// What wakes the writer.
const POKES: Channel<EmergencyStop> = Channel::ad_hoc("test/pokes", Qos::SMALL);
/// What it writes, once.
const LATCHED: Channel<EmergencyStop> = Channel::ad_hoc("test/latched", Qos::STATE);

#[derive(Default)]
struct Pokes {
    pokes: Drain<EmergencyStop>,
}

impl Inputs for Pokes {
    fn visit<V: InputVisitor>(&mut self, v: &mut V) -> Result<(), V::Error> {
        v.drain(POKES, &mut self.pokes)
    }
}

#[derive(Default)]
struct State {
    state: Out<EmergencyStop>,
}

impl Outputs for State {
    fn visit<V: OutputVisitor>(&mut self, v: &mut V) -> Result<(), V::Error> {
        v.output(LATCHED, &mut self.state)
    }
}

/// Writes the latched state once, at its first poke, as the executive writes the stop: on
/// change only.
#[derive(Default)]
struct WritesOnce {
    written: bool,
}

impl Node for WritesOnce {
    type Inputs = Pokes;
    type Outputs = State;
    type Devices = ();
    type Error = std::convert::Infallible;

    fn name(&self) -> &str {
        "writes-once"
    }

    fn inputs(&self) -> Pokes {
        Pokes::default()
    }

    fn outputs(&self) -> State {
        State::default()
    }

    fn step(
        &mut self,
        tick: &NodeTick,
        _readings: Option<&()>,
        inputs: &Pokes,
        _commands: &mut (),
        outputs: &mut State,
    ) -> Result<(), Self::Error> {
        if !self.written && !inputs.pokes.items().is_empty() {
            let mut state = EmergencyStop {
                engaged: 1,
                ..EmergencyStop::default()
            };
            state.header.capture_ns = tick.now_ns;
            outputs.state.send(state);
            self.written = true;
        }
        Ok(())
    }
}

/// The first message on `subscriber`, read until the watchdog (the history comes without an
/// event, so the test reads every few milliseconds).
fn first(subscriber: &Subscriber<EmergencyStop>) -> Option<EmergencyStop> {
    let deadline = Instant::now() + WATCHDOG;
    while Instant::now() < deadline {
        if let Some(message) = subscriber.receive().expect("receive") {
            return Some(*message);
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    None
}

#[test]
fn a_late_joiner_of_a_latched_channel_gets_the_last_value_at_the_writers_next_tick() {
    let domain = ScratchDomain::new("latched");
    let context = Context::new(&domain, "test").expect("context");
    let mut pokes = context.publisher(POKES).expect("pokes");
    let early = context.subscriber(LATCHED).expect("early reader");
    let stop = Arc::new(AtomicBool::new(false));
    let writer = {
        let (domain, stop) = (domain.clone(), Arc::clone(&stop));
        std::thread::spawn(move || {
            let context = Context::new(&domain, "writer").expect("context");
            let options = WakeOptions {
                stop: Some(&stop),
                ..WakeOptions::sensor(
                    Wake::Input {
                        topic: POKES.spec.topic,
                    },
                    1,
                )
            };
            let finished = run_on_wake(&context, WritesOnce::default(), (), options).expect("run");
            finished.result.map_err(|error| error.to_string())
        })
    };

    // The writer's ports exist once the early reader is connected to it; poke until the one
    // write arrives (a poke before its subscriber exists is lost).
    let written = loop {
        pokes.publish(&EmergencyStop::default()).expect("poke");
        std::thread::sleep(Duration::from_millis(20));
        if let Some(message) = early.receive().expect("receive") {
            break *message;
        }
    };
    assert_eq!(written.engaged, 1);
    assert_eq!(written.header.msg_seq, 1);

    // A reader that joins now, after the only write.
    let late = context.subscriber(LATCHED).expect("late reader");
    std::thread::sleep(Duration::from_millis(50));
    // One more tick of the writer, which sends nothing.
    pokes.publish(&EmergencyStop::default()).expect("poke");
    let latched = first(&late).expect("the late reader got the last value");
    assert_eq!(latched.header.msg_seq, 1, "{latched:?}");
    assert_eq!(latched.engaged, 1);

    stop.store(true, Ordering::SeqCst);
    // The stop flag is read at each heartbeat (woken by pokes or the heartbeat interval).
    let ticks = writer
        .join()
        .expect("writer thread")
        .expect("run ends cleanly");
    assert!(ticks >= 2, "{ticks} ticks");
    assert!(early.receive().expect("receive").is_none(), "written once");
}
