//! The laser scanner as a runtime node ([`LaserTask`]): `laser/scan_request` ->
//! [`ScanService`] on the ALACS unit ([`UnitDevices`]) -> `laser/scan_result`. The tick around
//! it (the stop first, device faults, the operator's mode, health) is the runtime's
//! ([`harvest_node::Runner`]).
//!
//! Requests are answered one at a time in arrival order; those that arrive meanwhile wait in
//! the task's queue. A scan is one device exchange per tick (laser on, 5 x move + capture,
//! laser off: [`crate::interval_scan`]): the tick writes the exchange, the next tick reads its
//! answer, processes a captured image and writes the next exchange, and the task says it has
//! more work ([`Node::has_more_work`]) until the scan ended, so that the runtime ticks it back
//! to back with its heartbeat in between. An apple out of view or reach is answered in the
//! tick its request is read, without an exchange (`scan_duration_ns` 0).
//!
//! The emergency stop: the runtime switches the laser off before the step; the step then ends
//! the scan under way without another exchange and answers its request with status
//! `DeviceError` (never resumed), and answers every request read while the stop is engaged
//! the same way. The operator's mode restricts new targets and manual moves; a scan is
//! neither, so the laser scans in every mode.
//!
//! Health: the answers so far are the progress; the figure is the apple being scanned
//! (`scanning_apple`) or the last answer's duration (`last_scan_ms`); degraded while the last
//! scan failed on the device.

use std::collections::VecDeque;

use harvest_hw::alacs::AlacsUnit;
use harvest_ipc::catalogue::{LASER_SCAN_REQUEST, LASER_SCAN_RESULT};
use harvest_ipc::payloads::{LaserScanRequest, LaserScanResult, LaserScanStatus};
use harvest_node::ports::{Drain, Out};
use harvest_node::{InputVisitor, Inputs, Node, NodeHealth, NodeTick, OutputVisitor, Outputs};

use crate::interval_scan::{IntervalScan, UnitExchange};
use crate::scan::ScanError;
use crate::scan_counts::ScanCounts;
use crate::service::{ScanRequestError, ScanService};
use crate::unit_devices::{UnitDevices, UnitFailure, UnitReading};

/// The channel the laser reads.
#[derive(Default)]
pub struct LaserInputs {
    requests: Drain<LaserScanRequest>,
}

impl Inputs for LaserInputs {
    fn visit<V: InputVisitor>(&mut self, v: &mut V) -> Result<(), V::Error> {
        v.drain(LASER_SCAN_REQUEST, &mut self.requests)
    }
}

/// The channel the laser writes.
#[derive(Default)]
pub struct LaserOutputs {
    results: Out<LaserScanResult>,
}

impl Outputs for LaserOutputs {
    fn visit<V: OutputVisitor>(&mut self, v: &mut V) -> Result<(), V::Error> {
        v.output(LASER_SCAN_RESULT, &mut self.results)
    }
}

/// The scan under way.
#[derive(Debug)]
struct InFlight {
    request: LaserScanRequest,
    scan: IntervalScan<UnitFailure>,
    started_ns: u64,
}

/// The laser scanner on a unit of type `U` (module documentation).
pub struct LaserTask<U> {
    unit: std::marker::PhantomData<fn() -> U>,
    service: ScanService,
    queue: VecDeque<LaserScanRequest>,
    in_flight: Option<InFlight>,
    counts: ScanCounts,
    result: LaserScanResult,
}

impl<U> LaserTask<U> {
    pub fn new(service: ScanService) -> Self {
        Self {
            unit: std::marker::PhantomData,
            service,
            queue: VecDeque::new(),
            in_flight: None,
            counts: ScanCounts::default(),
            result: LaserScanResult::default(),
        }
    }

    pub fn service(&self) -> &ScanService {
        &self.service
    }

    /// Answers given so far.
    pub fn counts(&self) -> &ScanCounts {
        &self.counts
    }

    /// Requests read and not answered yet (the one being scanned included).
    pub fn pending(&self) -> usize {
        self.queue.len() + usize::from(self.in_flight.is_some())
    }

    /// Answers `request`: its scan ended (or could not start: `scan` is the error), `scan_ns`
    /// after it started.
    fn answer(
        &mut self,
        request: &LaserScanRequest,
        scan: Result<IntervalScan<UnitFailure>, ScanRequestError<UnitFailure>>,
        scan_ns: u64,
        outputs: &mut LaserOutputs,
    ) {
        let outcome = self.service.complete(request, scan, &mut self.result);
        self.result.scan_duration_ns = scan_ns;
        outputs.results.send(self.result);
        let result = &self.result;
        let stopped = matches!(outcome, Err(ScanRequestError::Scan(ScanError::Stopped)));
        self.counts.count(result, stopped);
        let (request_seq, apple_id) = (request.request_seq, request.apple_id);
        match outcome {
            Ok(scan) => tracing::debug!(
                request_seq,
                apple_id,
                selected = scan.selected,
                position_in_camera_m = ?result.position_in_camera_m,
                scan_ms = result.scan_duration_ns / 1_000_000,
                "apple scanned"
            ),
            Err(error) if stopped => {
                tracing::info!(request_seq, apple_id, %error, "scan refused or ended")
            }
            Err(error) if result.status == LaserScanStatus::DeviceError => {
                tracing::warn!(request_seq, apple_id, %error, "scan failed")
            }
            Err(error) => tracing::debug!(
                request_seq,
                apple_id,
                status = ?result.status,
                %error,
                "scan gave no position"
            ),
        }
    }

    /// Ends the scan under way and answers every request read with the stop's status.
    fn answer_all_stopped(&mut self, now_ns: u64, outputs: &mut LaserOutputs) {
        if let Some(InFlight {
            request,
            mut scan,
            started_ns,
        }) = self.in_flight.take()
        {
            scan.stop();
            self.answer(
                &request,
                Ok(scan),
                now_ns.saturating_sub(started_ns),
                outputs,
            );
        }
        while let Some(request) = self.queue.pop_front() {
            self.answer(
                &request,
                Err(ScanRequestError::Scan(ScanError::Stopped)),
                0,
                outputs,
            );
        }
    }

    /// Feeds the reading (the answer to the exchange written at the previous tick) to the scan
    /// under way, and answers its request once it ended.
    fn advance(&mut self, now_ns: u64, reading: Option<&UnitReading>, outputs: &mut LaserOutputs) {
        let Some(in_flight) = &mut self.in_flight else {
            return;
        };
        if let Some(reading) = reading {
            match &reading.outcome {
                Ok(answer) => self.service.answered(
                    &mut in_flight.scan,
                    *answer,
                    reading.image(),
                    reading.device_ns,
                ),
                Err(failure) => in_flight.scan.failed(failure.clone(), reading.device_ns),
            }
        }
        if in_flight.scan.is_done()
            && let Some(InFlight {
                request,
                scan,
                started_ns,
            }) = self.in_flight.take()
        {
            self.answer(
                &request,
                Ok(scan),
                now_ns.saturating_sub(started_ns),
                outputs,
            );
        }
    }

    /// Starts the oldest waiting request's scan; those out of view or reach are answered at once.
    fn start_next(&mut self, now_ns: u64, outputs: &mut LaserOutputs) {
        while self.in_flight.is_none()
            && let Some(request) = self.queue.pop_front()
        {
            match self.service.start(&request) {
                Ok(scan) => {
                    tracing::debug!(
                        request_seq = request.request_seq,
                        apple_id = request.apple_id,
                        waiting = self.queue.len(),
                        "scan started"
                    );
                    self.in_flight = Some(InFlight {
                        request,
                        scan,
                        started_ns: now_ns,
                    });
                }
                Err(error) => self.answer(&request, Err(error), 0, outputs),
            }
        }
    }
}

impl<U: AlacsUnit> Node for LaserTask<U> {
    type Inputs = LaserInputs;
    type Outputs = LaserOutputs;
    type Devices = UnitDevices<U>;
    type Error = std::convert::Infallible;

    fn name(&self) -> &str {
        "laser"
    }

    fn inputs(&self) -> LaserInputs {
        LaserInputs::default()
    }

    fn outputs(&self) -> LaserOutputs {
        LaserOutputs::default()
    }

    /// Requests answered.
    fn progress(&self) -> Option<u64> {
        Some(self.counts.answered)
    }

    /// A scan is under way or a request waits.
    fn has_more_work(&self) -> bool {
        self.pending() > 0
    }

    fn health(&mut self) -> Option<NodeHealth> {
        let (detail, value) = match &self.in_flight {
            Some(in_flight) => ("scanning_apple", u64::from(in_flight.request.apple_id)),
            None => ("last_scan_ms", self.counts.last_scan_ns / 1_000_000),
        };
        Some(NodeHealth {
            state: self.counts.run_state(),
            detail,
            value,
            device_error: None,
        })
    }

    fn step(
        &mut self,
        tick: &NodeTick,
        reading: Option<&UnitReading>,
        inputs: &LaserInputs,
        command: &mut Option<UnitExchange>,
        outputs: &mut LaserOutputs,
    ) -> Result<(), Self::Error> {
        self.queue.extend(inputs.requests.items().iter().copied());
        *command = None;
        if tick.emergency_stop {
            self.answer_all_stopped(tick.now_ns, outputs);
            return Ok(());
        }
        self.advance(tick.now_ns, reading, outputs);
        self.start_next(tick.now_ns, outputs);
        if let Some(in_flight) = &self.in_flight {
            *command = in_flight.scan.next_exchange();
            tracing::trace!(
                request_seq = in_flight.request.request_seq,
                exchange = ?*command,
                "ALACS exchange"
            );
        }
        Ok(())
    }

    /// The run ends (the runtime switched the laser off): every request read is answered with
    /// the stop's status.
    fn on_exit(&mut self, now_ns: u64, outputs: &mut LaserOutputs) {
        self.answer_all_stopped(now_ns, outputs);
    }
}

#[cfg(test)]
mod tests;
