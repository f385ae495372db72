//! The node contract: what a node declares and what it does each tick.
//!
//! Lifecycle (what may happen where): the process (or the evaluation) builds the node and its
//! devices, opening everything that can fail to open; [`crate::tick::Runner`] then calls
//! [`Node::step`] and [`Node::finish`] once per tick, and [`Node::on_exit`] once at the end.
//! `step` and `finish` do no I/O, read no clock (the time is [`NodeTick::now_ns`]) and, after
//! the first ticks, allocate nothing.

use harvest_hw::ErrorKind;
use harvest_ipc::payloads::ProcessRunState;
use harvest_robot_model::Obedience;

/// What the runner tells the node about this tick.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NodeTick {
    /// The tick's time (the stack's monotonic clock, or the simulated clock), ns.
    pub now_ns: u64,
    /// Ticks so far, this one included.
    pub count: u64,
    /// The emergency stop is engaged (the devices were put in their safe state before the
    /// step; the node's device commands are not written).
    pub emergency_stop: bool,
    /// The device read failed this tick (the devices are in their safe state; no readings).
    pub device_fault: bool,
    /// What the operator's mode allows ([`harvest_robot_model::obedience`](mod@harvest_robot_model::obedience)).
    pub obedience: Obedience,
}

/// What a node's heartbeat says, when the node knows better than the runner (a node that
/// owns a device driver itself, a node whose main figure is not its period).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NodeHealth {
    pub state: ProcessRunState,
    /// The one figure worth showing, and its value (e.g. `frame_age_ns`).
    pub detail: &'static str,
    pub value: u64,
    /// The kind of a device error met since the previous heartbeat.
    pub device_error: Option<ErrorKind>,
}

/// What became of the node's device commands this tick.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Applied {
    /// Written to the devices.
    Written,
    /// Not written: the stop or a failed read came first (the devices were stopped or held).
    Safe,
    /// The devices refused them; the runner told the devices to hold.
    Refused,
}

/// The devices a node owns (ros2_control's hardware interface): read before the step, written
/// after it, and a safe state that needs nothing from a reading.
pub trait Devices {
    /// One tick's readings.
    type Readings;
    /// One tick's commands.
    type Commands: Default;
    /// The devices' error; its kind ([`harvest_hw::ErrorKind`]) reaches the heartbeat.
    type Error: harvest_hw::DeviceError;

    /// The emergency stop's state (brake, close every valve). Called before anything else on
    /// every tick the stop is engaged, and at the end of the run; must not depend on a
    /// reading. An implementation may skip the exchange when the device already confirmed
    /// the state and nothing was written since.
    fn stop(&mut self) -> Result<(), Self::Error>;

    /// What a device fault leads to: hold where it is (the arm brakes; the valves stay as
    /// they are, so a carried apple is not dropped). Called after a failed read or a refused
    /// write, when the stop is not engaged; must not depend on a reading.
    fn hold(&mut self) -> Result<(), Self::Error>;

    /// The newest readings; `None` while the device has nothing yet.
    fn read(&mut self, now_ns: u64) -> Result<Option<Self::Readings>, Self::Error>;

    /// Writes one tick's commands.
    fn write(&mut self, commands: &Self::Commands) -> Result<(), Self::Error>;
}

/// A node of the robot (see the crate documentation).
pub trait Node {
    /// Its input slots, one per channel read.
    type Inputs: crate::transport::Inputs;
    /// Its output slots, one per channel written.
    type Outputs: crate::transport::Outputs;
    /// The devices it owns (`()` when none).
    type Devices: Devices;
    /// Why a step failed for good (ends the run).
    type Error: std::error::Error + Send + Sync + 'static;

    /// The node's name in logs.
    fn name(&self) -> &str;

    /// Its empty input slots (the channels may depend on the node, e.g. which arm).
    fn inputs(&self) -> Self::Inputs;

    /// Its empty output slots.
    fn outputs(&self) -> Self::Outputs;

    /// What the heartbeat counts as the node's progress (its main channel's messages); `None`:
    /// the ticks.
    fn progress(&self) -> Option<u64> {
        None
    }

    /// Whether the node has work left that needs another tick at once, without waiting for
    /// what wakes it (e.g. a scan of several device exchanges, one per tick). A runtime woken
    /// by an input (`harvest_runtime::Wake::Input`) ticks again right away while this is true,
    /// with the heartbeat between ticks; a periodic or device-paced run ignores it. Default:
    /// never.
    fn has_more_work(&self) -> bool {
        false
    }

    /// What the heartbeat says (asked once per heartbeat); `None`: the runner's run state
    /// (degraded while a device exchange fails) and figure.
    fn health(&mut self) -> Option<NodeHealth> {
        None
    }

    /// One tick: the readings of this tick (`None` before the device's first readings and on
    /// a failed read), the inputs, the commands to write and the outputs to fill.
    fn step(
        &mut self,
        tick: &NodeTick,
        readings: Option<&<Self::Devices as Devices>::Readings>,
        inputs: &Self::Inputs,
        commands: &mut <Self::Devices as Devices>::Commands,
        outputs: &mut Self::Outputs,
    ) -> Result<(), Self::Error>;

    /// After the commands were written (or not): outputs that depend on it.
    fn finish(&mut self, _tick: &NodeTick, _applied: Applied, _outputs: &mut Self::Outputs) {}

    /// At the end of the run (signal, error), after the devices were put in their safe state:
    /// the last messages (e.g. "close my valve").
    fn on_exit(&mut self, _now_ns: u64, _outputs: &mut Self::Outputs) {}
}

/// No devices.
impl Devices for () {
    type Readings = ();
    type Commands = ();
    type Error = std::convert::Infallible;

    fn stop(&mut self) -> Result<(), Self::Error> {
        Ok(())
    }

    fn hold(&mut self) -> Result<(), Self::Error> {
        Ok(())
    }

    fn read(&mut self, _: u64) -> Result<Option<()>, Self::Error> {
        Ok(Some(()))
    }

    fn write(&mut self, _: &()) -> Result<(), Self::Error> {
        Ok(())
    }
}
