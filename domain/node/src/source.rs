//! [`Source`]: the node of a device that delivers large messages (a camera's frames, a
//! LiDAR's integrated clouds): each is captured straight into the node's loaned output
//! ([`Loaned`]) and sent, never copied on the way.
//!
//! A source is paced by its device (the runtime's device wake-up): its step blocks in the
//! driver's capture, which waits event-driven for the device and returns after at most the
//! source's timeout, so the heartbeat and a signal are seen. This is the one step that does
//! I/O, as a copper source task does: the device is the node's input. A capture that times
//! out keeps the loan (a driver may have begun filling it, see `harvest_hw::lidar::Lidar`);
//! failures are counted, reported by kind, and a streak longer than the limit ends the run
//! (the supervisor restarts the process).

use std::time::Duration;

use harvest_hw::rgbd_camera::RgbdCamera;
use harvest_hw::{AnyDeviceError, DeviceError, ErrorKind};
use harvest_ipc::catalogue::Channel;
use harvest_ipc::payload::Payload;
use harvest_ipc::payloads::{ProcessRunState, RgbdFrame};

use crate::in_place::Loaned;
use crate::node::{Node, NodeHealth, NodeTick};
use crate::transport::{OutputVisitor, Outputs};

/// What a source has counted, for the device's health report.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SourceCounts {
    /// Messages sent since start.
    pub sent: u64,
    /// Captures failed in a row (0 after a good one).
    pub failures_in_a_row: u32,
    /// The kind of a capture error since the previous heartbeat (reported once, even when the
    /// driver recovered before the heartbeat).
    pub error_since_heartbeat: Option<ErrorKind>,
}

/// A device that captures into a message in place.
pub trait Capture<T> {
    /// The driver's error.
    type Error: DeviceError;

    /// Blocks until the device delivers one message or `timeout`, writing it into `out`
    /// (loaned shared memory) with `header.capture_ns`. `false`: timeout (keep `out` for the
    /// next call).
    fn capture_into(&mut self, out: &mut T, timeout: Duration) -> Result<bool, Self::Error>;

    /// The heartbeat's state, detail and value. Default: starting before the first message,
    /// degraded while captures fail (`device_errors`: the failures in a row), else running.
    fn health(&self, counts: &SourceCounts) -> (ProcessRunState, &'static str, u64) {
        capture_health(counts)
    }
}

/// The default heartbeat of a capture device ([`Capture::health`]).
pub fn capture_health(counts: &SourceCounts) -> (ProcessRunState, &'static str, u64) {
    let state = if counts.failures_in_a_row > 0 {
        ProcessRunState::Degraded
    } else if counts.sent == 0 {
        ProcessRunState::Starting
    } else {
        ProcessRunState::Running
    };
    (state, "device_errors", u64::from(counts.failures_in_a_row))
}

/// Every RGB-D camera captures frames.
impl<C: RgbdCamera> Capture<RgbdFrame> for C {
    type Error = C::Error;

    fn capture_into(&mut self, out: &mut RgbdFrame, timeout: Duration) -> Result<bool, C::Error> {
        RgbdCamera::capture_into(self, out, timeout)
    }

    /// [`capture_health`], except that while captures succeed the detail is the first of the
    /// link's losses that is not zero (`lost_frames`, `missing_packets`, `resent_packets`):
    /// a camera on a network can lose frames without a capture ever failing.
    fn health(&self, counts: &SourceCounts) -> (ProcessRunState, &'static str, u64) {
        let default = capture_health(counts);
        if counts.failures_in_a_row > 0 {
            return default;
        }
        let link = RgbdCamera::health(self);
        [
            ("lost_frames", link.lost_frames),
            ("missing_packets", link.missing_packets),
            ("resent_packets", link.resent_packets),
        ]
        .into_iter()
        .find(|&(_, count)| count > 0)
        .map_or(default, |(detail, count)| (default.0, detail, count))
    }
}

/// Why a source ended its run.
#[derive(Debug, thiserror::Error)]
#[error("{failures} captures failed in a row: {error}")]
pub struct SourceError {
    pub failures: u32,
    /// The last capture's error, with its kind.
    #[source]
    pub error: AnyDeviceError,
}

/// The one output of a source.
pub struct SourceOutput<T: Payload + 'static> {
    channel: Channel<T>,
    pub message: Loaned<T>,
}

impl<T: Payload + 'static> Outputs for SourceOutput<T> {
    fn visit<V: OutputVisitor>(&mut self, v: &mut V) -> Result<(), V::Error> {
        v.loaned(self.channel, &mut self.message)
    }
}

/// A capture device as a node writing `channel` (module documentation).
pub struct Source<D, T: Payload + 'static> {
    name: &'static str,
    channel: Channel<T>,
    device: D,
    timeout: Duration,
    max_failures_in_a_row: u32,
    counts: SourceCounts,
}

impl<D, T: Payload + 'static> Source<D, T> {
    /// `device` captured into `channel`, waiting at most `timeout` per capture; more than
    /// `max_failures_in_a_row` failed captures in a row end the run.
    pub fn new(
        name: &'static str,
        channel: Channel<T>,
        device: D,
        timeout: Duration,
        max_failures_in_a_row: u32,
    ) -> Self {
        Self {
            name,
            channel,
            device,
            timeout,
            max_failures_in_a_row,
            counts: SourceCounts::default(),
        }
    }

    pub fn device(&self) -> &D {
        &self.device
    }

    pub fn counts(&self) -> &SourceCounts {
        &self.counts
    }
}

impl<D: Capture<T>, T: Payload + 'static> Node for Source<D, T> {
    type Inputs = ();
    type Outputs = SourceOutput<T>;
    type Devices = ();
    type Error = SourceError;

    fn name(&self) -> &str {
        self.name
    }

    fn inputs(&self) {}

    fn outputs(&self) -> SourceOutput<T> {
        SourceOutput {
            channel: self.channel,
            message: Loaned::default(),
        }
    }

    fn progress(&self) -> Option<u64> {
        Some(self.counts.sent)
    }

    fn health(&mut self) -> Option<NodeHealth> {
        let (state, detail, value) = self.device.health(&self.counts);
        Some(NodeHealth {
            state,
            detail,
            value,
            device_error: self.counts.error_since_heartbeat.take(),
        })
    }

    fn step(
        &mut self,
        _tick: &NodeTick,
        _readings: Option<&()>,
        _inputs: &(),
        _commands: &mut (),
        outputs: &mut SourceOutput<T>,
    ) -> Result<(), SourceError> {
        // No sample to lend: the transport reports why after the step.
        let Some(message) = outputs.message.sample_mut() else {
            return Ok(());
        };
        match self.device.capture_into(message, self.timeout) {
            Ok(true) => {
                self.counts.failures_in_a_row = 0;
                self.counts.sent += 1;
                outputs.message.send();
                tracing::trace!(source = self.name, sent = self.counts.sent, "captured");
            }
            Ok(false) => {}
            Err(error) => {
                self.counts.failures_in_a_row += 1;
                let kind = error.kind();
                self.counts.error_since_heartbeat = Some(kind);
                tracing::warn!(source = self.name, %error, %kind, "capture failed");
                if self.counts.failures_in_a_row > self.max_failures_in_a_row {
                    return Err(SourceError {
                        failures: self.counts.failures_in_a_row,
                        error: AnyDeviceError::new(error),
                    });
                }
            }
        }
        Ok(())
    }
}
