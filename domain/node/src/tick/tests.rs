//! The tick's rules, tested once for every node: a toy node with a device that fails on
//! command, run on the in-process backend.

use harvest_ipc::catalogue::{EMERGENCY_STOP, HARVEST_EVENTS, OPERATOR_MODE, VALVE_REQUEST};
use harvest_ipc::payloads::{
    EmergencyStop, HarvestEvent, OperatorModeCode, OperatorModeState, ProcessRunState, ValveRequest,
};
use harvest_robot_model::ModeSource;

use super::*;
use crate::Bus;
use crate::in_process::{Cursors, InProcess, Schedule};
use crate::node::{Applied, Devices, Node, NodeTick};
use crate::ports::{Drain, Out};
use crate::transport::{InputVisitor, Inputs, OutputVisitor, Outputs};

/// What the device was asked, in order.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Call {
    Stop,
    Hold,
    Read,
    Write(u32),
}

#[derive(Debug, Default)]
struct Device {
    fail_reads: bool,
    fail_writes: bool,
    calls: Vec<Call>,
}

#[derive(Debug, thiserror::Error)]
#[error("injected")]
struct Injected;

impl harvest_hw::DeviceError for Injected {
    fn kind(&self) -> harvest_hw::ErrorKind {
        harvest_hw::ErrorKind::Timeout
    }
}

impl Device {
    fn written(&self) -> Result<(), Injected> {
        if self.fail_writes {
            Err(Injected)
        } else {
            Ok(())
        }
    }
}

impl Devices for Device {
    type Readings = u32;
    type Commands = u32;
    type Error = Injected;

    fn stop(&mut self) -> Result<(), Injected> {
        self.calls.push(Call::Stop);
        self.written()
    }

    fn hold(&mut self) -> Result<(), Injected> {
        self.calls.push(Call::Hold);
        self.written()
    }

    fn read(&mut self, _: u64) -> Result<Option<u32>, Injected> {
        self.calls.push(Call::Read);
        if self.fail_reads {
            Err(Injected)
        } else {
            Ok(Some(7))
        }
    }

    fn write(&mut self, commands: &u32) -> Result<(), Injected> {
        self.calls.push(Call::Write(*commands));
        if self.fail_writes {
            Err(Injected)
        } else {
            Ok(())
        }
    }
}

#[derive(Default)]
struct Ins {
    requests: Drain<ValveRequest>,
}

impl Inputs for Ins {
    fn visit<V: InputVisitor>(&mut self, v: &mut V) -> Result<(), V::Error> {
        v.drain(VALVE_REQUEST, &mut self.requests)
    }
}

#[derive(Default)]
struct Outs {
    events: Out<HarvestEvent>,
}

impl Outputs for Outs {
    fn visit<V: OutputVisitor>(&mut self, v: &mut V) -> Result<(), V::Error> {
        v.output(HARVEST_EVENTS, &mut self.events)
    }
}

/// Echoes each valve request as an event; commands the request count; remembers every tick.
#[derive(Default)]
struct Toy {
    ticks: Vec<(NodeTick, Option<u32>)>,
    applied: Vec<Applied>,
    exited: bool,
}

impl Node for Toy {
    type Inputs = Ins;
    type Outputs = Outs;
    type Devices = Device;
    type Error = Injected;

    fn name(&self) -> &str {
        "toy"
    }

    fn inputs(&self) -> Ins {
        Ins::default()
    }

    fn outputs(&self) -> Outs {
        Outs::default()
    }

    fn step(
        &mut self,
        tick: &NodeTick,
        readings: Option<&u32>,
        inputs: &Ins,
        commands: &mut u32,
        outputs: &mut Outs,
    ) -> Result<(), Injected> {
        self.ticks.push((*tick, readings.copied()));
        *commands = inputs.requests.items().len() as u32 + 1;
        for request in inputs.requests.items() {
            outputs.events.send(HarvestEvent {
                apple_id: request.request_seq,
                ..HarvestEvent::default()
            });
        }
        Ok(())
    }

    fn finish(&mut self, _: &NodeTick, applied: Applied, _: &mut Outs) {
        self.applied.push(applied);
    }

    fn on_exit(&mut self, _: u64, _: &mut Outs) {
        self.exited = true;
    }
}

fn config(mode_source: ModeSource) -> RunnerConfig {
    RunnerConfig {
        max_read_failures: 3,
        mode_source,
    }
}

fn stop(engaged: bool) -> EmergencyStop {
    EmergencyStop {
        engaged: u8::from(engaged),
        ..EmergencyStop::default()
    }
}

fn tick(runner: &mut Runner<Toy>, bus: &mut Bus, cursors: &mut Cursors, now_ns: u64) {
    let mut transport = InProcess {
        bus,
        cursors,
        now_ns,
    };
    runner.tick(&mut transport, now_ns).expect("tick");
}

#[test]
fn the_stop_comes_before_the_device_read_and_no_command_is_written() {
    let mut bus = Bus::default();
    let mut cursors = Cursors::default();
    let mut runner = Runner::new(
        Toy::default(),
        Device::default(),
        config(ModeSource::Executive),
    );
    tick(&mut runner, &mut bus, &mut cursors, 1);
    assert_eq!(runner.devices().calls, [Call::Read, Call::Write(1)]);

    bus.publish(EMERGENCY_STOP, stop(true), 2);
    tick(&mut runner, &mut bus, &mut cursors, 3);
    // The stop is latched: it applies on every tick until released.
    tick(&mut runner, &mut bus, &mut cursors, 4);
    assert_eq!(
        runner.devices().calls[2..],
        [Call::Stop, Call::Read, Call::Stop, Call::Read]
    );
    assert!(runner.node().ticks[1].0.emergency_stop);
    assert_eq!(runner.node().applied[1..], [Applied::Safe, Applied::Safe]);

    bus.publish(EMERGENCY_STOP, stop(false), 5);
    tick(&mut runner, &mut bus, &mut cursors, 6);
    assert_eq!(runner.devices().calls[6..], [Call::Read, Call::Write(1)]);
}

#[test]
fn the_stop_wins_during_a_burst_of_device_errors() {
    let mut bus = Bus::default();
    let mut cursors = Cursors::default();
    let mut runner = Runner::new(
        Toy::default(),
        Device::default(),
        config(ModeSource::Executive),
    );
    tick(&mut runner, &mut bus, &mut cursors, 1);
    assert_eq!(runner.last_device_error(), None);
    // Reads and writes fail: the failed read alone means hold (tried, refused).
    {
        let device = &mut runner.devices;
        device.fail_reads = true;
        device.fail_writes = true;
    }
    tick(&mut runner, &mut bus, &mut cursors, 2);
    assert_eq!(runner.devices().calls[2..], [Call::Read, Call::Hold]);
    assert_eq!(runner.node().ticks[1], (runner.node().ticks[1].0, None));
    assert!(runner.node().ticks[1].0.device_fault);
    assert_eq!(runner.run_state(), ProcessRunState::Degraded);
    // The heartbeat's device error kind: the injected failure's.
    assert_eq!(
        runner.last_device_error(),
        Some(harvest_hw::ErrorKind::Timeout)
    );

    // The stop during the burst: the devices stopped first, on the very next tick.
    bus.publish(EMERGENCY_STOP, stop(true), 3);
    tick(&mut runner, &mut bus, &mut cursors, 4);
    assert_eq!(runner.devices().calls[4..], [Call::Stop, Call::Read]);
    assert!(runner.node().ticks[2].0.emergency_stop);
    assert_eq!(runner.node().applied[1..], [Applied::Safe, Applied::Safe]);

    // The third failed read in a row ends the run; the shutdown stops the devices.
    let mut transport = InProcess {
        bus: &mut bus,
        cursors: &mut cursors,
        now_ns: 5,
    };
    let error = runner
        .tick(&mut transport, 5)
        .expect_err("the streak's limit");
    assert!(
        matches!(error, TickError::Device { failures: 3, .. }),
        "{error}"
    );
    let Ok(()) = runner.shutdown(&mut transport, 6);
    assert_eq!(runner.devices().calls.last(), Some(&Call::Stop));
    assert!(runner.node().exited);
}

#[test]
fn a_refused_command_means_hold() {
    let mut bus = Bus::default();
    let mut cursors = Cursors::default();
    let mut runner = Runner::new(
        Toy::default(),
        Device::default(),
        config(ModeSource::Executive),
    );
    runner.devices.fail_writes = true;
    tick(&mut runner, &mut bus, &mut cursors, 1);
    assert_eq!(
        runner.devices().calls,
        [Call::Read, Call::Write(1), Call::Hold]
    );
    assert_eq!(runner.node().applied, [Applied::Refused]);
    assert_eq!(runner.run_state(), ProcessRunState::Degraded);
}

#[test]
fn no_mode_heard_holds_unless_running_without_an_operator() {
    let mut bus = Bus::default();
    let (mut a, mut b) = (Cursors::default(), Cursors::default());
    let mut held = Runner::new(
        Toy::default(),
        Device::default(),
        config(ModeSource::Executive),
    );
    let mut free = Runner::new(
        Toy::default(),
        Device::default(),
        config(ModeSource::WithoutOperator),
    );
    tick(&mut held, &mut bus, &mut a, 1);
    tick(&mut free, &mut bus, &mut b, 1);
    assert_eq!(held.node().ticks[0].0.obedience.targets_held, [true; 2]);
    assert_eq!(free.node().ticks[0].0.obedience.targets_held, [false; 2]);

    // A heard mode wins over the flag, the field hold included.
    let mode = OperatorModeState {
        mode: OperatorModeCode::Harvesting as u8,
        arms_enabled: [1, 1],
        field_hold: 1,
        ..OperatorModeState::default()
    };
    bus.publish(OPERATOR_MODE, mode, 2);
    tick(&mut held, &mut bus, &mut a, 3);
    tick(&mut free, &mut bus, &mut b, 3);
    assert_eq!(held.node().ticks[1].0.obedience.targets_held, [true; 2]);
    assert_eq!(free.node().ticks[1].0.obedience.targets_held, [true; 2]);
    // Remembered while no newer mode comes.
    tick(&mut free, &mut bus, &mut b, 4);
    assert_eq!(free.node().ticks[2].0.obedience.targets_held, [true; 2]);
}

#[test]
fn a_schedule_runs_nodes_in_time_order_and_each_reads_a_message_once() {
    let mut schedule = Schedule::new(0);
    let fast = schedule.add(
        Runner::new(
            Toy::default(),
            Device::default(),
            config(ModeSource::Executive),
        ),
        5,
        0,
    );
    let slow = schedule.add(
        Runner::new(
            Toy::default(),
            Device::default(),
            config(ModeSource::Executive),
        ),
        10,
        0,
    );
    for seq in 1..=3 {
        let request = ValveRequest {
            request_seq: seq,
            ..ValveRequest::default()
        };
        schedule.bus_mut().publish(VALVE_REQUEST, request, 0);
    }
    schedule.run_until(20).expect("run");
    let fast_node = schedule.runner::<Toy>(fast).expect("toy").node();
    let slow_node = schedule.runner::<Toy>(slow).expect("toy").node();
    let times = |node: &Toy| node.ticks.iter().map(|t| t.0.now_ns).collect::<Vec<_>>();
    assert_eq!(times(fast_node), [0, 5, 10, 15, 20]);
    assert_eq!(times(slow_node), [0, 10, 20]);
    // Both nodes saw the three requests once, on their first tick; each echoed them.
    let echoed = schedule
        .bus_mut()
        .latest(HARVEST_EVENTS)
        .map(|e| e.apple_id);
    assert_eq!(echoed, Some(3));
    assert_eq!(
        schedule
            .bus_mut()
            .publish(HARVEST_EVENTS, HarvestEvent::default(), 20),
        7
    );
    schedule.shutdown();
    assert!(schedule.runner::<Toy>(slow).expect("toy").node().exited);
}

#[test]
fn a_recorded_tick_names_the_stop_the_mode_the_readings_and_every_message_read() {
    use harvest_ipc::payloads::{DeviceErrorCode, DeviceRead, MODE_SLOT, StopHeard};

    let mut bus = Bus::default();
    let mut cursors = Cursors::default();
    let mut runner = Runner::new(
        Toy::default(),
        Device::default(),
        config(ModeSource::WithoutOperator),
    );
    runner.record_ticks();
    bus.publish(EMERGENCY_STOP, stop(true), 1);
    let mode_seq = bus.publish(OPERATOR_MODE, OperatorModeState::default(), 2);
    let first = bus.publish(VALVE_REQUEST, ValveRequest::default(), 3);
    let second = bus.publish(VALVE_REQUEST, ValveRequest::default(), 4);
    tick(&mut runner, &mut bus, &mut cursors, 10);

    let record = *runner.tick_record().expect("recorded");
    assert_eq!((record.header.capture_ns, record.tick), (10, 1));
    assert_eq!(record.emergency_stop_heard.get(), Ok(StopHeard::Engaged));
    assert_eq!(record.device_read.get(), Ok(DeviceRead::Readings));
    let readings: u32 =
        harvest_ipc::codec::decode_exact(record.readings.as_slice()).expect("readings");
    assert_eq!(readings, 7);
    assert_eq!(record.without_operator, 1);
    assert_eq!(record.inputs_complete, 1);
    let read: Vec<(u8, u64, u64)> = record
        .inputs
        .as_slice()
        .iter()
        .map(|input| (input.slot, input.msg_seq, input.publish_ns))
        .collect();
    assert_eq!(
        read,
        [(MODE_SLOT, mode_seq, 2), (0, first, 3), (0, second, 4)]
    );
    // Stopped: nothing written, so nothing refused.
    assert_eq!(record.write_error.get(), Ok(DeviceErrorCode::None));

    // Released, with the device refusing the commands and then failing to read.
    bus.publish(EMERGENCY_STOP, stop(false), 11);
    runner.devices.fail_writes = true;
    tick(&mut runner, &mut bus, &mut cursors, 12);
    let record = *runner.tick_record().expect("recorded");
    assert_eq!(record.tick, 2);
    assert_eq!(record.emergency_stop_heard.get(), Ok(StopHeard::Released));
    assert_eq!(record.write_error.get(), Ok(DeviceErrorCode::Timeout));
    assert!(record.inputs.is_empty());
    runner.devices.fail_reads = true;
    tick(&mut runner, &mut bus, &mut cursors, 13);
    let record = *runner.tick_record().expect("recorded");
    assert_eq!(record.emergency_stop_heard.get(), Ok(StopHeard::Nothing));
    assert_eq!(record.device_read.get(), Ok(DeviceRead::Failed));
    assert_eq!(record.read_error.get(), Ok(DeviceErrorCode::Timeout));
    assert!(record.readings.is_empty());
}
