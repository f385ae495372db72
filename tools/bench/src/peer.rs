//! `harvest bench-peer`: the sending process of one case.

use crate::affinity::pin_to_cpu;
use crate::control::{ACK, Control, END, GO_LATENCY, GO_STREAM, READY};
use crate::error::BenchError;
use crate::message::{BenchMessage, Phase};
use crate::options::{BenchPeerArgs, Transport};
use crate::payload_case::{PayloadCase, with_payload_type};
use crate::sender_write::PayloadWriter;
use crate::stats::latency_histogram;
use crate::transport::SendPort;
use crate::transport::copy::CopySender;
use crate::transport::ours::OursSender;
use crate::transport::raw::RawSender;
use harvest_ipc::Domain;
use std::time::{Duration, Instant};

/// Runs the sending side of one case: connects to the measuring process, sends the
/// stop-and-wait messages (each after the previous one was acknowledged), then the stream.
pub fn run_bench_peer(args: &BenchPeerArgs) -> Result<(), BenchError> {
    if let Some(cpu) = args.pin_cpu {
        pin_to_cpu(cpu)?;
    }
    let payload = PayloadCase::parse(&args.payload)?;
    with_payload_type!(payload, T => run_typed::<T>(args, payload))
}

fn run_typed<T: BenchMessage>(args: &BenchPeerArgs, case: PayloadCase) -> Result<(), BenchError> {
    let payload = case.name();
    let mut control = Control::connect(&args.control)?;
    let domain = Domain::new(&args.domain)?;
    let mut sender: Box<dyn SendPort<T>> = match args.transport {
        Transport::Ours => Box::new(OursSender::<T>::open(&domain, case)?),
        Transport::Iceoryx2 => Box::new(RawSender::<T>::open(&domain, args.mode, payload)?),
        Transport::UdsCopy => Box::new(CopySender::<T>::connect(&args.control, payload)?),
        Transport::ZenohTcp | Transport::ZenohShm => zenoh_sender::<T>(args, payload)?,
        Transport::CycloneDds => cyclonedds_sender::<T>(args, payload)?,
    };
    let mut writer = PayloadWriter::new(args.sender_write, std::mem::size_of::<T>());
    let mut send_call = latency_histogram()?;
    control.send(READY)?;

    control.expect(GO_LATENCY, "start of the latency phase")?;
    let plan = LatencyPlan::new(args.warmup, args.iterations, args.duration);
    let mut progress = LatencyProgress::default();
    loop {
        let phase = plan.next_phase(&mut progress, Instant::now());
        let call_ns = sender.send(phase, &mut writer)?;
        if matches!(phase, Phase::Measure | Phase::MeasureLast) {
            send_call.saturating_record(call_ns.max(1));
        }
        control.expect(ACK, "acknowledgement of a stop-and-wait message")?;
        if phase == Phase::MeasureLast {
            break;
        }
    }
    tracing::debug!(
        payload,
        warmup = progress.warmup_sent,
        measured = progress.measured_sent
    );

    control.expect(GO_STREAM, "start of the throughput phase")?;
    let stream_for = args.duration / 4;
    let window = stream_window::<T>();
    let mut in_flight = 0;
    let start = Instant::now();
    loop {
        while in_flight >= window {
            in_flight -= control.read_acks(in_flight)?;
        }
        let last = start.elapsed() >= stream_for;
        sender.send(
            if last {
                Phase::StreamLast
            } else {
                Phase::Stream
            },
            &mut writer,
        )?;
        in_flight += 1;
        if last {
            break;
        }
    }
    while in_flight > 0 {
        in_flight -= control.read_acks(in_flight)?;
    }
    control.expect(END, "end of the case")?;
    control.send_u64(send_call.value_at_quantile(0.5))?;
    Ok(())
}

/// The sending port of a Zenoh transport, connected to the receiver's `--zenoh-endpoint`.
#[cfg(feature = "zenoh")]
fn zenoh_sender<T: BenchMessage>(
    args: &BenchPeerArgs,
    payload: &'static str,
) -> Result<Box<dyn SendPort<T>>, BenchError> {
    use crate::transport::zenoh_shm::ZenohShmSender;
    use crate::transport::zenoh_tcp::ZenohTcpSender;
    let endpoint = args
        .zenoh_endpoint
        .as_deref()
        .ok_or_else(|| BenchError::InvalidOption {
            option: "zenoh-endpoint",
            value: "(missing)".to_owned(),
            reason: format!("{} needs the receiver's endpoint", args.transport.name()),
        })?;
    match args.transport {
        Transport::ZenohShm => Ok(Box::new(ZenohShmSender::<T>::connect(endpoint, payload)?)),
        Transport::ZenohTcp => Ok(Box::new(ZenohTcpSender::<T>::connect(endpoint, payload)?)),
        Transport::Ours | Transport::Iceoryx2 | Transport::UdsCopy | Transport::CycloneDds => {
            Err(BenchError::InvalidOption {
                option: "transport",
                value: args.transport.name().to_owned(),
                reason: "not a Zenoh transport".to_owned(),
            })
        }
    }
}

/// Without the `zenoh` feature: how to build it.
#[cfg(not(feature = "zenoh"))]
fn zenoh_sender<T: BenchMessage>(
    args: &BenchPeerArgs,
    _payload: &'static str,
) -> Result<Box<dyn SendPort<T>>, BenchError> {
    Err(BenchError::TransportNotBuilt {
        transport: args.transport.name(),
        feature: "zenoh",
    })
}

/// The sending port of Cyclone DDS, on the case's topic (named after `--control`).
#[cfg(feature = "cyclonedds")]
fn cyclonedds_sender<T: BenchMessage>(
    args: &BenchPeerArgs,
    payload: &'static str,
) -> Result<Box<dyn SendPort<T>>, BenchError> {
    use crate::transport::cyclonedds::CycloneDdsSender;
    Ok(Box::new(CycloneDdsSender::<T>::connect(
        &args.control,
        payload,
    )?))
}

/// Without the `cyclonedds` feature: how to build it.
#[cfg(not(feature = "cyclonedds"))]
fn cyclonedds_sender<T: BenchMessage>(
    args: &BenchPeerArgs,
    _payload: &'static str,
) -> Result<Box<dyn SendPort<T>>, BenchError> {
    Err(BenchError::TransportNotBuilt {
        transport: args.transport.name(),
        feature: "cyclonedds",
    })
}

/// Messages the throughput phase keeps in flight (sent, not yet acknowledged): the payload's
/// default subscriber buffer, so a default subscriber that keeps up loses nothing, on every
/// transport alike. Throughput is then the sustained loss-free rate, not a rate under overload.
pub fn stream_window<T: BenchMessage>() -> usize {
    T::qos().default_buffer_size.max(1)
}

/// When the stop-and-wait phase warms up, measures, and ends.
#[derive(Debug, Clone, Copy)]
struct LatencyPlan {
    warmup: u64,
    iterations: u64,
    /// Limit of the measured part; warm-up is limited to a quarter of it.
    duration: Duration,
}

#[derive(Debug, Default, Clone, Copy)]
struct LatencyProgress {
    started: Option<Instant>,
    measure_started: Option<Instant>,
    warmup_sent: u64,
    measured_sent: u64,
}

impl LatencyPlan {
    fn new(warmup: u64, iterations: u64, duration: Duration) -> Self {
        Self {
            warmup,
            iterations: iterations.max(1),
            duration,
        }
    }

    /// The phase of the next message to send at `now`, counting it as sent.
    fn next_phase(&self, progress: &mut LatencyProgress, now: Instant) -> Phase {
        let started = *progress.started.get_or_insert(now);
        let warming = progress.measure_started.is_none()
            && progress.warmup_sent < self.warmup
            && now.duration_since(started) < self.duration / 4;
        if warming {
            progress.warmup_sent += 1;
            return Phase::Warmup;
        }
        let measure_started = *progress.measure_started.get_or_insert(now);
        progress.measured_sent += 1;
        let out_of_time = now.duration_since(measure_started) >= self.duration;
        if progress.measured_sent >= self.iterations || out_of_time {
            Phase::MeasureLast
        } else {
            Phase::Measure
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plan_counts_warmup_then_iterations() {
        let plan = LatencyPlan::new(2, 3, Duration::from_secs(100));
        let mut progress = LatencyProgress::default();
        let now = Instant::now();
        let phases: Vec<_> = (0..5)
            .map(|_| plan.next_phase(&mut progress, now))
            .collect();
        assert_eq!(
            phases,
            vec![
                Phase::Warmup,
                Phase::Warmup,
                Phase::Measure,
                Phase::Measure,
                Phase::MeasureLast
            ]
        );
    }

    #[test]
    fn plan_stops_on_time() {
        let plan = LatencyPlan::new(100, 1000, Duration::from_secs(4));
        let mut progress = LatencyProgress::default();
        let t0 = Instant::now();
        assert_eq!(plan.next_phase(&mut progress, t0), Phase::Warmup);
        // Warm-up ends after a quarter of the duration.
        let t1 = t0 + Duration::from_secs(1);
        assert_eq!(plan.next_phase(&mut progress, t1), Phase::Measure);
        assert_eq!(
            plan.next_phase(&mut progress, t1 + Duration::from_secs(1)),
            Phase::Measure
        );
        // Measuring ends after the duration; the message sent then is the last.
        assert_eq!(
            plan.next_phase(&mut progress, t1 + Duration::from_secs(4)),
            Phase::MeasureLast
        );
    }

    #[test]
    fn zero_warmup_measures_at_once() {
        let plan = LatencyPlan::new(0, 1, Duration::from_secs(1));
        let mut progress = LatencyProgress::default();
        assert_eq!(
            plan.next_phase(&mut progress, Instant::now()),
            Phase::MeasureLast
        );
    }
}
