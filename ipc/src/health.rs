//! Heartbeats every process sends on the health channel (supervisor's hung-process detection).

use crate::catalogue::PROCESS_HEALTH;
use crate::clock::MonotonicClock;
use crate::context::Context;
use crate::error::{OpenChannelError, SendError};
use crate::fixed_string::FixedString;
use crate::payloads::{DeviceErrorCode, ProcessHealth, ProcessRunState};
use crate::period_stats::PeriodSummary;
use crate::publisher::Publisher;
use std::time::Duration;

/// How often a process reports. The supervisor's hang timeout is a multiple of this.
pub const HEARTBEAT_PERIOD: Duration = Duration::from_millis(500);

/// Publishes this process's heartbeat.
pub struct HealthReporter {
    publisher: Publisher<ProcessHealth>,
    process_name: FixedString<32>,
    pid: u32,
    last_device_error: DeviceErrorCode,
}

impl HealthReporter {
    /// Opens the publisher of `system/health` for this process.
    pub fn new(context: &Context) -> Result<Self, OpenChannelError> {
        Ok(Self {
            publisher: context.publisher(PROCESS_HEALTH)?,
            process_name: FixedString::new(context.process_name()),
            pid: std::process::id(),
            last_device_error: DeviceErrorCode::None,
        })
    }

    /// Records the kind of a device error the process met; every following heartbeat carries
    /// it ([`ProcessHealth::last_device_error`]) until the next one. The process maps its
    /// driver's error with `harvest_hw::ErrorKind`'s conversion.
    pub fn note_device_error(&mut self, kind: DeviceErrorCode) {
        self.last_device_error = kind;
    }

    /// The kind of the last device error noted ([`DeviceErrorCode::None`]: none).
    pub fn last_device_error(&self) -> DeviceErrorCode {
        self.last_device_error
    }

    /// Sends one heartbeat. `main_channel_count` counts messages on the process's main channel
    /// since start; `detail`/`detail_value` carry one figure worth showing (e.g. a latency).
    pub fn report(
        &mut self,
        run_state: ProcessRunState,
        main_channel_count: u64,
        detail: &str,
        detail_value: u64,
    ) -> Result<(), SendError> {
        self.send(run_state, main_channel_count, detail, detail_value, 0)
    }

    /// Sends the heartbeat of a control loop: the detail is the period's p99 (`period_p99_us`)
    /// and the deadline misses so far go with it.
    pub fn report_control_loop(
        &mut self,
        run_state: ProcessRunState,
        main_channel_count: u64,
        period: &PeriodSummary,
    ) -> Result<(), SendError> {
        self.send(
            run_state,
            main_channel_count,
            "period_p99_us",
            period.p99_ns / 1000,
            period.deadline_misses,
        )
    }

    fn send(
        &mut self,
        run_state: ProcessRunState,
        main_channel_count: u64,
        detail: &str,
        detail_value: u64,
        deadline_misses: u64,
    ) -> Result<(), SendError> {
        let process_name = self.process_name;
        let pid = self.pid;
        let last_device_error = self.last_device_error;
        self.publisher
            .publish_with(MonotonicClock::read_ns(), |health| {
                health.process_name = process_name;
                health.pid = pid;
                health.run_state.set(run_state);
                health.last_device_error.set(last_device_error);
                health._reserved = [0; 2];
                health.main_channel_count = main_channel_count;
                health.detail = FixedString::new(detail);
                health.detail_value = detail_value;
                health.deadline_misses = deadline_misses;
            })?;
        Ok(())
    }
}
