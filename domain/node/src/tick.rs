//! The one tick every node runs ([`Runner::tick`]); the order and the rules are in the crate
//! documentation.

use harvest_hw::{AnyDeviceError, DeviceError, ErrorKind};
use harvest_ipc::failure_streak::FailureStreak;
use harvest_ipc::payloads::{OperatorModeState, ProcessRunState};
use harvest_robot_model::{ModeSource, obedience};

use crate::node::{Applied, Devices, Node, NodeTick};
use crate::tick_record::TickRecorder;
use crate::transport::Transport;

/// What the runner needs to know besides the node.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RunnerConfig {
    /// Failed device reads in a row after which the run ends (the supervisor restarts the
    /// process).
    pub max_read_failures: u32,
    /// Where the operator's mode comes from (no mode heard: hold, unless told
    /// [`ModeSource::WithoutOperator`]).
    pub mode_source: ModeSource,
}

/// Why a tick ended the run.
#[derive(Debug, thiserror::Error)]
pub enum TickError<T: std::error::Error, N: std::error::Error> {
    /// The transport failed.
    #[error(transparent)]
    Transport(T),
    /// The node failed for good.
    #[error("{node}: {error}")]
    Node { node: String, error: N },
    /// The device failed to answer too many times in a row.
    #[error("{node}: {failures} device reads failed in a row: {error}")]
    Device {
        node: String,
        failures: u32,
        /// The last read's error, with its kind.
        #[source]
        error: AnyDeviceError,
    },
}

/// A node with its devices, slots and the state of the rules (the stop, the mode, the device
/// failure streaks).
pub struct Runner<N: Node> {
    node: N,
    devices: N::Devices,
    inputs: N::Inputs,
    outputs: N::Outputs,
    commands: <N::Devices as Devices>::Commands,
    config: RunnerConfig,
    emergency_stop: bool,
    mode: Option<OperatorModeState>,
    read_failures: FailureStreak,
    write_failures: FailureStreak,
    last_device_error: Option<ErrorKind>,
    ticks: u64,
    /// What each tick saw, when asked ([`Self::record_ticks`]).
    recorder: Option<TickRecorder<<N::Devices as Devices>::Readings>>,
}

impl<N: Node> Runner<N> {
    pub fn new(node: N, devices: N::Devices, config: RunnerConfig) -> Self {
        Self {
            inputs: node.inputs(),
            outputs: node.outputs(),
            node,
            devices,
            commands: Default::default(),
            config,
            emergency_stop: false,
            mode: None,
            read_failures: FailureStreak::new(config.max_read_failures),
            // A refused safe state or command is reported, never a reason to stop trying.
            write_failures: FailureStreak::new(u32::MAX),
            last_device_error: None,
            ticks: 0,
            recorder: None,
        }
    }

    /// From now on each tick is written down ([`crate::tick_record`]); the last tick's record
    /// is [`Self::tick_record`].
    pub fn record_ticks(&mut self)
    where
        <N::Devices as Devices>::Readings: serde::Serialize,
    {
        self.recorder = Some(TickRecorder::new());
    }

    /// What the last tick saw, when ticks are recorded.
    pub fn tick_record(&self) -> Option<&harvest_ipc::payloads::NodeTickRecord> {
        self.recorder.as_ref().map(TickRecorder::record)
    }

    /// The devices, to be given what they answer (a re-run on recorded readings).
    pub fn devices_mut(&mut self) -> &mut N::Devices {
        &mut self.devices
    }

    pub fn node(&self) -> &N {
        &self.node
    }

    pub fn node_mut(&mut self) -> &mut N {
        &mut self.node
    }

    pub fn devices(&self) -> &N::Devices {
        &self.devices
    }

    /// The node's slots (a transport opens its ports from them).
    pub fn slots_mut(&mut self) -> (&mut N::Inputs, &mut N::Outputs) {
        (&mut self.inputs, &mut self.outputs)
    }

    /// Ticks so far.
    pub fn ticks(&self) -> u64 {
        self.ticks
    }

    /// Whether the emergency stop was engaged at the last tick.
    pub fn emergency_stop(&self) -> bool {
        self.emergency_stop
    }

    /// What the heartbeat says: degraded while the last device read or write failed.
    pub fn run_state(&self) -> ProcessRunState {
        match self.write_failures.run_state() {
            ProcessRunState::Running => self.read_failures.run_state(),
            degraded => degraded,
        }
    }

    /// The kind of the last failed device exchange (`None`: none since start), for the heartbeat.
    pub fn last_device_error(&self) -> Option<ErrorKind> {
        self.last_device_error
    }

    /// Failed device exchanges since start: reads, writes (the safe state included).
    pub fn device_failures(&self) -> (u64, u64) {
        (self.read_failures.total(), self.write_failures.total())
    }

    /// Stops the devices (`stop`) or holds them (`hold`); a refusal is counted.
    fn make_safe(&mut self, stop: bool) {
        let (result, what) = if stop {
            (self.devices.stop(), "stop command")
        } else {
            (self.devices.hold(), "hold command")
        };
        match result {
            Ok(()) => self.write_failures.succeeded(),
            Err(error) => {
                self.last_device_error = Some(error.kind());
                self.write_failures.failed(what, &error);
            }
        }
    }

    /// One tick at `now_ns` (crate documentation). An error ends the run; call
    /// [`Self::shutdown`] after it as after a signal.
    pub fn tick<T: Transport>(
        &mut self,
        transport: &mut T,
        now_ns: u64,
    ) -> Result<(), TickError<T::Error, N::Error>> {
        self.ticks += 1;
        if let Some(recorder) = &mut self.recorder {
            let without_operator = self.config.mode_source == ModeSource::WithoutOperator;
            recorder.begin(now_ns, self.ticks, without_operator);
        }
        // 1. The stop first, applied whatever the devices do.
        let stop_heard = transport.emergency_stop().map_err(TickError::Transport)?;
        if let Some(engaged) = stop_heard {
            self.emergency_stop = engaged;
        }
        if let Some(recorder) = &mut self.recorder {
            recorder.stop_heard(stop_heard);
        }
        let mut safe = false;
        if self.emergency_stop {
            self.make_safe(true);
            safe = true;
        }

        // 2. The devices; a failed read means the safe state.
        let (readings, device_fault) = match self.devices.read(now_ns) {
            Ok(readings) => {
                self.read_failures.succeeded();
                if let Some(recorder) = &mut self.recorder {
                    recorder.read(Ok(readings.as_ref()));
                }
                (readings, false)
            }
            Err(error) => {
                self.last_device_error = Some(error.kind());
                if let Some(recorder) = &mut self.recorder {
                    recorder.read(Err(error.kind()));
                }
                let limit = self.read_failures.failed("device read", &error);
                if !safe {
                    self.make_safe(false);
                    safe = true;
                }
                if let Some(failures) = limit {
                    return Err(TickError::Device {
                        node: self.node.name().to_owned(),
                        failures,
                        error: AnyDeviceError::new(error),
                    });
                }
                (None, true)
            }
        };

        // 3. The operator's mode, by the one rule.
        if let Some(mode) = transport.operator_mode().map_err(TickError::Transport)? {
            if let Some(recorder) = &mut self.recorder {
                recorder.mode_heard(&mode);
            }
            self.mode = Some(mode);
        }
        let tick = NodeTick {
            now_ns,
            count: self.ticks,
            emergency_stop: self.emergency_stop,
            device_fault,
            obedience: obedience(self.mode.as_ref(), self.config.mode_source, now_ns),
        };

        // 4. Inputs, step, commands.
        transport
            .read_inputs(&mut self.inputs)
            .map_err(TickError::Transport)?;
        if let Some(recorder) = &mut self.recorder {
            recorder.inputs(&mut self.inputs);
        }
        self.node
            .step(
                &tick,
                readings.as_ref(),
                &self.inputs,
                &mut self.commands,
                &mut self.outputs,
            )
            .map_err(|error| TickError::Node {
                node: self.node.name().to_owned(),
                error,
            })?;
        let applied = if safe {
            Applied::Safe
        } else {
            match self.devices.write(&self.commands) {
                Ok(()) => {
                    self.write_failures.succeeded();
                    Applied::Written
                }
                Err(error) => {
                    self.last_device_error = Some(error.kind());
                    if let Some(recorder) = &mut self.recorder {
                        recorder.write_refused(error.kind());
                    }
                    self.write_failures.failed("device command", &error);
                    self.make_safe(false);
                    Applied::Refused
                }
            }
        };

        // 5. Outputs.
        self.node.finish(&tick, applied, &mut self.outputs);
        transport
            .publish(&mut self.outputs)
            .map_err(TickError::Transport)
    }

    /// The end of a run (signal or error): the devices stopped, then the node's last messages.
    pub fn shutdown<T: Transport>(
        &mut self,
        transport: &mut T,
        now_ns: u64,
    ) -> Result<(), T::Error> {
        self.make_safe(true);
        self.node.on_exit(now_ns, &mut self.outputs);
        transport.publish(&mut self.outputs)
    }
}

#[cfg(test)]
mod tests;
