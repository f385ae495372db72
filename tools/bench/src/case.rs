//! One run of one case (payload x transport x mode) on the measuring side: start the peer,
//! pace its stop-and-wait messages, record one-way latencies, then count its stream.
//!
//! Throughput: the peer streams for a quarter of `--duration`, keeping at most a window of
//! unacknowledged messages in flight (the payload's default subscriber buffer, see
//! [`crate::peer::stream_window`]), so the rate is the sustained loss-free one; it is the
//! delivered messages over the time from the first message's publish to the last's receipt.
//!
//! One-way latency = receive time - `publish_ns`, both `CLOCK_MONOTONIC` on this host
//! (`harvest_ipc::MonotonicClock`). `publish_ns` is stamped after the sender wrote the payload,
//! right before it hands the message to the transport (for the copying baseline: before
//! encoding). The receive time is read as soon as the message is available to the receiver
//! (zero-copy: the sample was taken; copying: it was decoded into the receiver's memory). The
//! receiver then checks a sample of the payload's lines outside the measured interval.

use crate::control::{ACK, Control, END, GO_LATENCY, GO_STREAM, READY};
use crate::error::BenchError;
use crate::message::{BenchMessage, Phase};
use crate::options::{BenchPeerArgs, PEER_SUBCOMMAND, Settings, Transport, WakeMode};
use crate::payload_case::{PayloadCase, with_payload_type};
use crate::socket_io::socket_error;
use crate::stats::{LatencySummary, StreamTally, Throughput, latency_histogram};
use crate::transport::ReceivePort;
use crate::transport::copy::CopyReceiver;
use crate::transport::ours::OursReceiver;
use crate::transport::raw::RawReceiver;
use crate::watchdog::Watchdog;
use harvest_ipc::{Domain, Flow};
use serde::Serialize;
use std::os::unix::net::UnixListener;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Duration;

/// Slack on top of a phase's nominal length before the peer counts as stuck.
const PHASE_GRACE: Duration = Duration::from_secs(20);

/// What to run.
#[derive(Debug, Clone, Copy)]
pub struct CaseSpec<'a> {
    pub payload: PayloadCase,
    pub transport: Transport,
    pub mode: WakeMode,
    pub settings: &'a Settings,
    pub domain: &'a Domain,
    /// Unique within the run (names the control socket).
    pub index: usize,
}

impl CaseSpec<'_> {
    pub fn label(&self) -> String {
        format!(
            "{}/{}/{}",
            self.payload,
            self.transport.name(),
            self.mode.name()
        )
    }
}

/// The numbers of one run.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct RunResult {
    pub latency: LatencySummary,
    /// Median time the sender spent writing the payload (capture_ns to publish_ns), not part
    /// of the latency.
    pub producer_write_p50_ns: u64,
    /// Median time the sender spent in the transport's send call after `publish_ns` (part of
    /// the latency: the sender's share; the rest is the receiver waking up and receiving).
    pub sender_send_call_p50_ns: u64,
    pub throughput: Throughput,
}

/// Runs one case once.
pub fn run_case(spec: &CaseSpec<'_>) -> Result<RunResult, BenchError> {
    with_payload_type!(spec.payload, T => run_typed::<T>(spec))
}

/// Removes the control socket file when the case ends.
struct SocketFile(PathBuf);

impl Drop for SocketFile {
    fn drop(&mut self) {
        if let Err(error) = std::fs::remove_file(&self.0) {
            tracing::debug!(path = %self.0.display(), %error, "control socket already removed");
        }
    }
}

fn run_typed<T: BenchMessage>(spec: &CaseSpec<'_>) -> Result<RunResult, BenchError> {
    let name = spec.payload.name();
    let settings = spec.settings;
    let path = std::env::temp_dir().join(format!(
        "harvest-bench-{}-{}.sock",
        std::process::id(),
        spec.index
    ));
    // A socket file of an earlier process with the same pid would make bind fail.
    let _ = std::fs::remove_file(&path);
    let listener = UnixListener::bind(&path).map_err(socket_error("control", &path))?;
    let _socket_file = SocketFile(path.clone());

    // The zero-copy and Zenoh receivers exist before the peer starts, so its first message
    // finds them (the Zenoh sender also waits until it sees the subscriber).
    let mut zenoh_endpoint = None;
    let mut receiver: Option<Box<dyn ReceivePort<T>>> = match spec.transport {
        Transport::Ours => Some(Box::new(OursReceiver::<T>::open(
            spec.domain,
            spec.mode,
            spec.payload,
        )?)),
        Transport::Iceoryx2 => Some(Box::new(RawReceiver::<T>::open(
            spec.domain,
            spec.mode,
            name,
        )?)),
        Transport::UdsCopy => None,
        Transport::ZenohTcp | Transport::ZenohShm => {
            let (receiver, endpoint) = zenoh_receiver::<T>(spec)?;
            zenoh_endpoint = Some(endpoint);
            Some(receiver)
        }
        Transport::CycloneDds => Some(cyclonedds_receiver::<T>(spec, &path)?),
    };
    let mut watchdog = Watchdog::new(spawn_peer(spec, &path, zenoh_endpoint)?, spec.label());
    watchdog.start_phase("connect", PHASE_GRACE);
    let mut control = Control::accept(&listener, &path, &mut watchdog)?;
    let mut receiver = match receiver.take() {
        Some(receiver) => receiver,
        None => Box::new(CopyReceiver::<T>::accept(
            &listener,
            &path,
            spec.mode,
            name,
            &mut watchdog,
        )?),
    };
    control.expect_watched(READY, "peer ready", &mut watchdog)?;

    // Latency: stop-and-wait, one message in flight.
    let mut latency = latency_histogram()?;
    let mut producer_write = latency_histogram()?;
    control.send(GO_LATENCY)?;
    watchdog.start_phase(
        "latency",
        settings.duration + settings.duration / 4 + PHASE_GRACE,
    );
    receiver.run_phase(&mut watchdog, &mut |message: &T, recv_ns| {
        let header = *message.header();
        let phase = settings.sender_write.check(message, name)?;
        match phase {
            Phase::Warmup => {}
            Phase::Measure | Phase::MeasureLast => {
                latency.saturating_record(recv_ns.saturating_sub(header.publish_ns).max(1));
                producer_write
                    .saturating_record(header.publish_ns.saturating_sub(header.capture_ns).max(1));
            }
            Phase::Stream | Phase::StreamLast => {
                return Err(BenchError::UnexpectedPhase {
                    payload: name,
                    msg_seq: header.msg_seq,
                    phase,
                    during: "latency",
                });
            }
        }
        control.send(ACK)?;
        Ok(if phase == Phase::MeasureLast {
            Flow::Stop
        } else {
            Flow::Continue
        })
    })?;

    // Throughput: a quarter of --duration, at most a window of messages in flight.
    let mut tally = StreamTally::default();
    control.send(GO_STREAM)?;
    watchdog.start_phase("throughput", settings.duration / 4 + PHASE_GRACE);
    receiver.run_phase(&mut watchdog, &mut |message: &T, recv_ns| {
        let header = *message.header();
        let phase = settings.sender_write.check(message, name)?;
        match phase {
            Phase::Stream | Phase::StreamLast => {
                tally.add(header.msg_seq, header.publish_ns, recv_ns);
                control.send(ACK)?;
            }
            Phase::Warmup | Phase::Measure | Phase::MeasureLast => {
                return Err(BenchError::UnexpectedPhase {
                    payload: name,
                    msg_seq: header.msg_seq,
                    phase,
                    during: "throughput",
                });
            }
        }
        Ok(if phase == Phase::StreamLast {
            Flow::Stop
        } else {
            Flow::Continue
        })
    })?;
    control.send(END)?;
    watchdog.start_phase("end", PHASE_GRACE);
    let sender_send_call_p50_ns = control.read_u64_watched(&mut watchdog)?;
    watchdog.wait_exit(PHASE_GRACE)?;
    drop(receiver);

    let result = RunResult {
        latency: LatencySummary::from_histogram(&latency),
        producer_write_p50_ns: producer_write.value_at_quantile(0.5),
        sender_send_call_p50_ns,
        throughput: tally.throughput(spec.payload.size_bytes()),
    };
    tracing::info!(
        case = watchdog.case(),
        samples = result.latency.samples,
        p50_ns = result.latency.p50_ns,
        p99_ns = result.latency.p99_ns,
        msgs_per_s = result.throughput.msgs_per_s,
        "case done"
    );
    Ok(result)
}

/// The receiving port of a Zenoh transport and the loopback endpoint it listens on (for the
/// peer's `--zenoh-endpoint`).
#[cfg(feature = "zenoh")]
fn zenoh_receiver<T: BenchMessage>(
    spec: &CaseSpec<'_>,
) -> Result<(Box<dyn ReceivePort<T>>, String), BenchError> {
    use crate::transport::zenoh_link::free_loopback_endpoint;
    use crate::transport::zenoh_shm::ZenohShmReceiver;
    use crate::transport::zenoh_tcp::ZenohTcpReceiver;
    let name = spec.payload.name();
    let endpoint = free_loopback_endpoint(spec.transport)?;
    let receiver: Box<dyn ReceivePort<T>> = match spec.transport {
        Transport::ZenohShm => Box::new(ZenohShmReceiver::<T>::listen(&endpoint, spec.mode, name)?),
        Transport::ZenohTcp => Box::new(ZenohTcpReceiver::<T>::listen(&endpoint, spec.mode, name)?),
        Transport::Ours | Transport::Iceoryx2 | Transport::UdsCopy | Transport::CycloneDds => {
            return Err(BenchError::InvalidOption {
                option: "transports",
                value: spec.transport.name().to_owned(),
                reason: "not a Zenoh transport".to_owned(),
            });
        }
    };
    Ok((receiver, endpoint))
}

/// Without the `zenoh` feature: how to build it.
#[cfg(not(feature = "zenoh"))]
fn zenoh_receiver<T: BenchMessage>(
    spec: &CaseSpec<'_>,
) -> Result<(Box<dyn ReceivePort<T>>, String), BenchError> {
    Err(BenchError::TransportNotBuilt {
        transport: spec.transport.name(),
        feature: "zenoh",
    })
}

/// The receiving port of Cyclone DDS, on the case's topic (named after `control`).
#[cfg(feature = "cyclonedds")]
fn cyclonedds_receiver<T: BenchMessage>(
    spec: &CaseSpec<'_>,
    control: &Path,
) -> Result<Box<dyn ReceivePort<T>>, BenchError> {
    use crate::transport::cyclonedds::CycloneDdsReceiver;
    Ok(Box::new(CycloneDdsReceiver::<T>::open(
        control,
        spec.mode,
        spec.payload.name(),
    )?))
}

/// Without the `cyclonedds` feature: how to build it.
#[cfg(not(feature = "cyclonedds"))]
fn cyclonedds_receiver<T: BenchMessage>(
    spec: &CaseSpec<'_>,
    _control: &Path,
) -> Result<Box<dyn ReceivePort<T>>, BenchError> {
    Err(BenchError::TransportNotBuilt {
        transport: spec.transport.name(),
        feature: "cyclonedds",
    })
}

fn spawn_peer(
    spec: &CaseSpec<'_>,
    control: &Path,
    zenoh_endpoint: Option<String>,
) -> Result<std::process::Child, BenchError> {
    let exe = std::env::current_exe().map_err(|source| BenchError::Spawn {
        exe: PathBuf::from("<current exe>"),
        source,
    })?;
    let peer = BenchPeerArgs {
        control: control.to_owned(),
        domain: spec.domain.name().to_owned(),
        transport: spec.transport,
        mode: spec.mode,
        payload: spec.payload.name().to_owned(),
        warmup: spec.settings.warmup,
        iterations: spec.settings.iterations,
        duration: spec.settings.duration,
        pin_cpu: spec.settings.pin_cpus.map(|(_, sender)| sender),
        sender_write: spec.settings.sender_write,
        zenoh_endpoint,
    };
    Command::new(&exe)
        .arg(PEER_SUBCOMMAND)
        .args(peer.to_command_line())
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .spawn()
        .map_err(|source| BenchError::Spawn { exe, source })
}
