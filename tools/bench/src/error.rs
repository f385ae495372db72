//! Why a benchmark run (or its peer process) failed.

use std::path::PathBuf;

/// Everything that can end `harvest bench ipc` or `harvest bench-peer` early.
#[derive(Debug, thiserror::Error)]
pub enum BenchError {
    /// A `--sizes` entry names no compiled payload.
    #[error("--sizes: unknown payload size {value:?}; supported: {supported}")]
    UnknownPayload { value: String, supported: String },
    /// `--pin-cpus` is not one or two CPU numbers below the machine's CPU count.
    #[error("--pin-cpus {value:?}: {reason}")]
    InvalidPinCpus { value: String, reason: String },
    /// An option value is out of range.
    #[error("--{option} {value}: {reason}")]
    InvalidOption {
        option: &'static str,
        value: String,
        reason: String,
    },
    /// A transport was asked for that this build does not have.
    #[error(
        "--transports {transport}: this build does not have it; build with the `{feature}` \
feature: `cargo build --release --features harvest-bench/{feature}` (the `harvest` binary) or \
`cargo run --release -p harvest-bench --features {feature} --bin harvest-bench-peer -- bench ipc ...`"
    )]
    TransportNotBuilt {
        transport: &'static str,
        feature: &'static str,
    },
    /// A call of a peer transport (Zenoh, Cyclone DDS) failed.
    #[error("{transport}: {operation} on {key:?} failed: {reason}")]
    PeerTransport {
        transport: &'static str,
        operation: &'static str,
        key: String,
        reason: String,
    },
    /// The benchmark domain name was rejected by harvest-ipc.
    #[error(transparent)]
    Domain(#[from] harvest_ipc::domain::InvalidDomain),
    /// The transport (node, channel, send, receive, wait set) failed.
    #[error(transparent)]
    Ipc(#[from] harvest_ipc::error::IpcError),
    /// A raw iceoryx2 call (the baseline without our layer) failed.
    #[error("raw iceoryx2 baseline: {operation} on service {service:?} failed: {reason}")]
    Iceoryx2 {
        operation: &'static str,
        service: String,
        reason: String,
    },
    /// Encoding or decoding a message of a copying transport (uds-copy, zenoh-tcp) failed.
    #[error("{operation} of a {payload} message failed: {source}")]
    Codec {
        operation: &'static str,
        payload: &'static str,
        #[source]
        source: harvest_ipc::codec::CodecError,
    },
    /// A socket (control connection or the copying baseline's data stream) failed.
    #[error("{what} socket {path}: {source}")]
    Socket {
        what: &'static str,
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The other side of a socket closed it in the middle of the run.
    #[error("{what} socket {path}: closed by the other process")]
    SocketClosed { what: &'static str, path: PathBuf },
    /// The control protocol saw an unexpected byte.
    #[error("control protocol: expected {expected:?} but got {got:?} ({context})")]
    Protocol {
        expected: char,
        got: char,
        context: &'static str,
    },
    /// The peer process could not be started.
    #[error("cannot start the peer process {exe}: {source}")]
    Spawn {
        exe: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The peer process ended before its case was finished.
    #[error("peer process for {case} exited early with {status}")]
    PeerExited {
        case: String,
        status: std::process::ExitStatus,
    },
    /// The peer did not make progress in time.
    #[error("peer process for {case}: no progress within {waited_s:.1} s ({phase})")]
    PeerTimeout {
        case: String,
        phase: &'static str,
        waited_s: f64,
    },
    /// A received payload did not hold the values its sender wrote.
    #[error(
        "{payload} message msg_seq {msg_seq}: cache line {line} holds {found:#018x}, \
expected {expected:#018x} (stale or torn payload)"
    )]
    Corrupt {
        payload: &'static str,
        msg_seq: u64,
        line: usize,
        expected: u64,
        found: u64,
    },
    /// A message of one phase arrived while another was running.
    #[error("{payload} message msg_seq {msg_seq}: phase {phase:?} during the {during} phase")]
    UnexpectedPhase {
        payload: &'static str,
        msg_seq: u64,
        phase: crate::message::Phase,
        during: &'static str,
    },
    /// A copying-baseline frame announced an impossible length.
    #[error("{path}: frame of {length} bytes announced, at most {max} expected for {payload}")]
    BadFrame {
        path: PathBuf,
        payload: &'static str,
        length: u64,
        max: usize,
    },
    /// A received message carried an unknown phase code.
    #[error("{payload} message msg_seq {msg_seq}: unknown phase code {code}")]
    UnknownPhase {
        payload: &'static str,
        msg_seq: u64,
        code: u64,
    },
    /// sched_setaffinity / sched_getaffinity failed.
    #[error("cannot pin to CPU {cpu}: {source}")]
    Affinity {
        cpu: usize,
        #[source]
        source: nix::Error,
    },
    /// The latency histogram could not be created.
    #[error("latency histogram: {reason}")]
    Histogram { reason: String },
    /// The run was interrupted by SIGINT/SIGTERM.
    #[error("interrupted by a termination signal")]
    Interrupted,
    /// Writing the JSON report or the SVG plot failed.
    #[error("cannot write {path}: {source}")]
    WriteOutput {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The stack under test (`harvest up`) ended while the pipeline benchmark was collecting.
    #[error("the stack under test ended early with {status} (log {log}):\n{tail}")]
    StackEnded {
        status: std::process::ExitStatus,
        log: PathBuf,
        tail: String,
    },
    /// The stack under test could not be stopped or waited for.
    #[error("cannot stop the stack under test (log {log})")]
    StackStop { log: PathBuf },
    /// Serializing the JSON report failed.
    #[error("cannot serialize the report as JSON: {0}")]
    Json(#[from] serde_json::Error),
}

harvest_ipc::from_ipc_errors!(BenchError);
