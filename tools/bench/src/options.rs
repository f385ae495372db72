//! Command-line options of `harvest bench ipc` and of the hidden `harvest bench-peer`, and the
//! settings they resolve to.

use crate::error::BenchError;
use crate::payload_case::PayloadCase;
use crate::sender_write::SenderWrite;
use serde::Serialize;
use std::path::PathBuf;
use std::time::Duration;

/// The subcommand (of the same executable) that runs the sending peer process.
pub const PEER_SUBCOMMAND: &str = "bench-peer";

/// The transport measured.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, clap::ValueEnum, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Transport {
    /// Our layer: harvest_ipc `Publisher`/`Subscriber` on the payload's catalogue channel, or an
    /// ad-hoc channel (`Channel::ad_hoc`) for the sweep sizes.
    #[value(name = "ours")]
    Ours,
    /// iceoryx2 publish-subscribe used directly, without our layer.
    #[value(name = "iceoryx2")]
    Iceoryx2,
    /// Copying baseline: codec-encoded messages over a Unix domain stream socket.
    #[value(name = "uds-copy")]
    UdsCopy,
    /// Zenoh publish-subscribe over loopback TCP (shared memory off): the copying baseline's
    /// codec-encoded messages through Zenoh instead of a raw socket. Needs the `zenoh` feature.
    #[value(name = "zenoh-tcp")]
    ZenohTcp,
    /// Zenoh publish-subscribe with its shared-memory transport: the sender allocates from a
    /// Zenoh SHM provider and writes the message in place. Needs the `zenoh` feature.
    #[value(name = "zenoh-shm")]
    ZenohShm,
    /// Eclipse Cyclone DDS (ROS 2's usual DDS) through Debian's `libddsc`: the copying
    /// baseline's codec-encoded messages as a reliable DDS topic. Needs the `cyclonedds`
    /// feature and `cyclonedds-dev`.
    #[value(name = "cyclonedds")]
    CycloneDds,
}

impl Transport {
    pub const ALL: [Transport; 6] = [
        Self::Ours,
        Self::Iceoryx2,
        Self::UdsCopy,
        Self::ZenohTcp,
        Self::ZenohShm,
        Self::CycloneDds,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Self::Ours => "ours",
            Self::Iceoryx2 => "iceoryx2",
            Self::UdsCopy => "uds-copy",
            Self::ZenohTcp => "zenoh-tcp",
            Self::ZenohShm => "zenoh-shm",
            Self::CycloneDds => "cyclonedds",
        }
    }

    /// Whether this build can measure the transport (the Zenoh peers need the `zenoh` feature,
    /// Cyclone DDS the `cyclonedds` feature).
    pub fn is_built(self) -> bool {
        match self {
            Self::Ours | Self::Iceoryx2 | Self::UdsCopy => true,
            Self::ZenohTcp | Self::ZenohShm => cfg!(feature = "zenoh"),
            Self::CycloneDds => cfg!(feature = "cyclonedds"),
        }
    }

    /// The cargo feature that builds the transport (none for the ones always built).
    pub fn feature(self) -> Option<&'static str> {
        match self {
            Self::Ours | Self::Iceoryx2 | Self::UdsCopy => None,
            Self::ZenohTcp | Self::ZenohShm => Some("zenoh"),
            Self::CycloneDds => Some("cyclonedds"),
        }
    }

    /// The transports this build can measure: the default of `--transports`.
    pub fn built() -> Vec<Transport> {
        Self::ALL.into_iter().filter(|t| t.is_built()).collect()
    }

    /// Fails with how to rebuild if this build cannot measure the transport.
    pub fn ensure_built(self) -> Result<(), BenchError> {
        if self.is_built() {
            Ok(())
        } else {
            Err(BenchError::TransportNotBuilt {
                transport: self.name(),
                feature: self.feature().unwrap_or("?"),
            })
        }
    }
}

/// How the receiver learns that a message arrived.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, clap::ValueEnum, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum WakeMode {
    /// Sleep in a wait set (iceoryx2 event / blocking socket read) until woken.
    #[value(name = "event")]
    Event,
    /// Spin on non-blocking receives.
    #[value(name = "poll")]
    Poll,
}

impl WakeMode {
    pub const ALL: [WakeMode; 2] = [Self::Event, Self::Poll];

    pub fn name(self) -> &'static str {
        match self {
            Self::Event => "event",
            Self::Poll => "poll",
        }
    }
}

/// `harvest bench ipc`: one-way latency and throughput between two processes, for our layer,
/// raw iceoryx2, a copying socket baseline and (with the `zenoh` feature) Zenoh over loopback
/// TCP and over its shared memory, over payloads from 64 B to 16 MiB.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct BenchIpcArgs {
    /// Unmeasured messages before measuring, per case (stopped early after a quarter of
    /// --duration) [default: 100; --quick: 5]
    #[arg(long)]
    pub warmup: Option<u64>,
    /// Measured stop-and-wait messages per case [default: 2000; --quick: 50]
    #[arg(long)]
    pub iterations: Option<u64>,
    /// Time limit of a case's latency phase (fewer samples if reached); its throughput phase
    /// streams for a quarter of it. E.g. `2s`, `500ms` [default: 2s; --quick: 200ms]
    #[arg(long, value_parser = parse_duration)]
    pub duration: Option<Duration>,
    /// Payloads, comma-separated: sizes 64B, 256B, 1KiB, 4KiB, 16KiB, 64KiB, 256KiB, 1MiB, 2MiB,
    /// 4MiB, 8MiB, 16MiB and the catalogue types scan-request, detections, rgbd
    /// [default: 64B,1KiB,16KiB,256KiB,1MiB,4MiB,8MiB,16MiB,scan-request,detections,rgbd]
    #[arg(long, value_delimiter = ',')]
    pub sizes: Vec<String>,
    /// Transports to measure; zenoh-tcp and zenoh-shm need a build with the `zenoh` feature, cyclonedds one with the `cyclonedds` feature
    /// [default: every transport this build has]
    #[arg(long, value_delimiter = ',')]
    pub transports: Vec<Transport>,
    /// Wake-up modes to measure [default: both]
    #[arg(long, value_delimiter = ',')]
    pub modes: Vec<WakeMode>,
    /// Pin the receiver (this process) and the sender (peer) to these CPUs: `RECEIVER,SENDER`,
    /// or one CPU for both
    #[arg(long, value_delimiter = ',')]
    pub pin_cpus: Vec<usize>,
    /// Runs per case (separate peer processes); the report gives the median of each number
    /// [default: 3; --quick: 1]
    #[arg(long)]
    pub repeats: Option<usize>,
    /// What the sender writes before each send: `full` (every line of the payload, the fair
    /// test), or the diagnostics `none` (only the phase code) and `elsewhere` (as many lines
    /// into a private buffer of the payload's size, not the message) [default: full]
    #[arg(long, value_enum)]
    pub sender_write: Option<SenderWrite>,
    /// A small run for tests and CI (small counts; explicit options still win)
    #[arg(long)]
    pub quick: bool,
    /// Write the report as JSON to this file
    #[arg(long, value_name = "PATH")]
    pub json: Option<PathBuf>,
    /// Write a latency-vs-size plot (SVG) to this file
    #[arg(long, value_name = "PATH")]
    pub svg: Option<PathBuf>,
}

/// `harvest bench-peer` (hidden): the sending process of one benchmark case, started by
/// `harvest bench ipc`.
#[derive(Debug, Clone, clap::Args)]
pub struct BenchPeerArgs {
    /// Control socket of the receiving process
    #[arg(long, value_name = "PATH")]
    pub control: PathBuf,
    /// iceoryx2 domain of the run
    #[arg(long)]
    pub domain: String,
    #[arg(long)]
    pub transport: Transport,
    #[arg(long)]
    pub mode: WakeMode,
    /// Payload name (see `bench ipc --sizes`)
    #[arg(long)]
    pub payload: String,
    #[arg(long)]
    pub warmup: u64,
    #[arg(long)]
    pub iterations: u64,
    #[arg(long, value_parser = parse_duration)]
    pub duration: Duration,
    /// CPU to pin this process to
    #[arg(long)]
    pub pin_cpu: Option<usize>,
    #[arg(long, value_enum, default_value = "full")]
    pub sender_write: SenderWrite,
    /// Zenoh endpoint the receiver listens on, e.g. `tcp/127.0.0.1:40123` (Zenoh transports)
    #[arg(long)]
    pub zenoh_endpoint: Option<String>,
}

impl BenchPeerArgs {
    /// The command line (after the subcommand) that reproduces these arguments.
    pub fn to_command_line(&self) -> Vec<String> {
        let mut line = vec![
            "--control".to_owned(),
            self.control.display().to_string(),
            "--domain".to_owned(),
            self.domain.clone(),
            "--transport".to_owned(),
            self.transport.name().to_owned(),
            "--mode".to_owned(),
            self.mode.name().to_owned(),
            "--payload".to_owned(),
            self.payload.clone(),
            "--warmup".to_owned(),
            self.warmup.to_string(),
            "--iterations".to_owned(),
            self.iterations.to_string(),
            "--duration".to_owned(),
            format!("{}ms", self.duration.as_millis()),
            "--sender-write".to_owned(),
            self.sender_write.name().to_owned(),
        ];
        if let Some(cpu) = self.pin_cpu {
            line.extend(["--pin-cpu".to_owned(), cpu.to_string()]);
        }
        if let Some(endpoint) = &self.zenoh_endpoint {
            line.extend(["--zenoh-endpoint".to_owned(), endpoint.clone()]);
        }
        line
    }
}

pub use harvest_ipc::duration::parse_duration;

/// Resolved settings of a run.
#[derive(Debug, Clone, Serialize)]
pub struct Settings {
    pub warmup: u64,
    pub iterations: u64,
    #[serde(rename = "duration_s", serialize_with = "serialize_seconds")]
    pub duration: Duration,
    pub repeats: usize,
    pub quick: bool,
    #[serde(serialize_with = "serialize_names")]
    pub payloads: Vec<PayloadCase>,
    pub transports: Vec<Transport>,
    pub modes: Vec<WakeMode>,
    /// (receiver CPU, sender CPU).
    pub pin_cpus: Option<(usize, usize)>,
    /// What the sender writes before each send (`full` is the fair test).
    pub sender_write: SenderWrite,
}

fn serialize_seconds<S: serde::Serializer>(value: &Duration, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_f64(value.as_secs_f64())
}

fn serialize_names<S: serde::Serializer>(value: &[PayloadCase], s: S) -> Result<S::Ok, S::Error> {
    s.collect_seq(value.iter().map(|case| case.name()))
}

impl Settings {
    /// Applies defaults (`--quick` ones if asked) and validates.
    pub fn resolve(args: &BenchIpcArgs, cpu_count: usize) -> Result<Self, BenchError> {
        let quick = args.quick;
        let settings = Self {
            warmup: args.warmup.unwrap_or(if quick { 5 } else { 100 }),
            iterations: args.iterations.unwrap_or(if quick { 50 } else { 2000 }),
            duration: args.duration.unwrap_or(if quick {
                Duration::from_millis(200)
            } else {
                Duration::from_secs(2)
            }),
            repeats: args.repeats.unwrap_or(if quick { 1 } else { 3 }),
            quick,
            payloads: resolve_payloads(&args.sizes)?,
            transports: dedup_or(&args.transports, &Transport::built()),
            modes: dedup_or(&args.modes, &WakeMode::ALL),
            pin_cpus: resolve_pin_cpus(&args.pin_cpus, cpu_count)?,
            sender_write: args.sender_write.unwrap_or_default(),
        };
        for transport in &settings.transports {
            transport.ensure_built()?;
        }
        if settings.iterations == 0 {
            return Err(BenchError::InvalidOption {
                option: "iterations",
                value: "0".to_owned(),
                reason: "at least one message must be measured".to_owned(),
            });
        }
        if settings.repeats == 0 {
            return Err(BenchError::InvalidOption {
                option: "repeats",
                value: "0".to_owned(),
                reason: "at least one run per case is needed".to_owned(),
            });
        }
        if settings.duration.is_zero() {
            return Err(BenchError::InvalidOption {
                option: "duration",
                value: "0".to_owned(),
                reason: "must be positive".to_owned(),
            });
        }
        Ok(settings)
    }
}

fn resolve_payloads(sizes: &[String]) -> Result<Vec<PayloadCase>, BenchError> {
    let mut payloads = if sizes.is_empty() {
        PayloadCase::DEFAULT.to_vec()
    } else {
        sizes
            .iter()
            .map(|size| PayloadCase::parse(size))
            .collect::<Result<Vec<_>, _>>()?
    };
    payloads.sort_by_key(|case| (case.size_bytes(), *case));
    payloads.dedup();
    Ok(payloads)
}

fn dedup_or<T: Copy + Ord>(given: &[T], all: &[T]) -> Vec<T> {
    let mut chosen = if given.is_empty() {
        all.to_vec()
    } else {
        given.to_vec()
    };
    chosen.sort_unstable();
    chosen.dedup();
    chosen
}

fn resolve_pin_cpus(
    cpus: &[usize],
    cpu_count: usize,
) -> Result<Option<(usize, usize)>, BenchError> {
    let value = || {
        cpus.iter()
            .map(ToString::to_string)
            .collect::<Vec<_>>()
            .join(",")
    };
    let pair = match cpus {
        [] => return Ok(None),
        [both] => (*both, *both),
        [receiver, sender] => (*receiver, *sender),
        _ => {
            return Err(BenchError::InvalidPinCpus {
                value: value(),
                reason: "give RECEIVER,SENDER or one CPU for both".to_owned(),
            });
        }
    };
    if pair.0 >= cpu_count || pair.1 >= cpu_count {
        return Err(BenchError::InvalidPinCpus {
            value: value(),
            reason: format!("this machine has CPUs 0..{}", cpu_count.saturating_sub(1)),
        });
    }
    Ok(Some(pair))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quick_defaults_yield_to_explicit_values() {
        let args = BenchIpcArgs {
            quick: true,
            iterations: Some(7),
            ..BenchIpcArgs::default()
        };
        let settings = Settings::resolve(&args, 2).expect("valid");
        assert_eq!(settings.iterations, 7);
        assert_eq!(settings.warmup, 5);
        assert_eq!(settings.repeats, 1);
        assert_eq!(settings.payloads.len(), PayloadCase::DEFAULT.len());
        assert_eq!(settings.transports, Transport::built());
    }

    #[test]
    fn zenoh_transports_need_the_feature() {
        let args = BenchIpcArgs {
            transports: vec![Transport::Ours, Transport::ZenohShm],
            ..BenchIpcArgs::default()
        };
        let resolved = Settings::resolve(&args, 2);
        if cfg!(feature = "zenoh") {
            assert!(Transport::built().contains(&Transport::ZenohShm));
            assert!(resolved.is_ok());
        } else {
            assert!(!Transport::built().contains(&Transport::ZenohShm));
            let message = resolved.expect_err("not built").to_string();
            assert!(
                message.contains("zenoh-shm") && message.contains("--features"),
                "{message}"
            );
        }
    }

    #[test]
    fn payloads_are_sorted_by_size_and_deduplicated() {
        let args = BenchIpcArgs {
            sizes: vec!["rgbd".into(), "64".into(), "64B".into(), "1K".into()],
            ..BenchIpcArgs::default()
        };
        let settings = Settings::resolve(&args, 2).expect("valid");
        assert_eq!(
            settings.payloads,
            vec![PayloadCase::Bytes64, PayloadCase::KiB1, PayloadCase::Rgbd]
        );
    }

    #[test]
    fn pin_cpus_are_checked_against_the_machine() {
        assert_eq!(resolve_pin_cpus(&[0, 1], 2).expect("valid"), Some((0, 1)));
        assert_eq!(resolve_pin_cpus(&[1], 2).expect("valid"), Some((1, 1)));
        assert!(resolve_pin_cpus(&[0, 2], 2).is_err());
        assert!(resolve_pin_cpus(&[0, 1, 1], 4).is_err());
    }

    #[test]
    fn peer_command_line_parses_back() {
        use clap::Parser;
        #[derive(clap::Parser)]
        struct Cli {
            #[command(flatten)]
            peer: BenchPeerArgs,
        }
        let peer = BenchPeerArgs {
            control: PathBuf::from("/tmp/x.sock"),
            domain: "bench-1".into(),
            transport: Transport::UdsCopy,
            mode: WakeMode::Poll,
            payload: "rgbd".into(),
            warmup: 3,
            iterations: 9,
            duration: Duration::from_millis(1500),
            pin_cpu: Some(1),
            sender_write: SenderWrite::Elsewhere,
            zenoh_endpoint: Some("tcp/127.0.0.1:40123".into()),
        };
        let mut argv = vec!["peer".to_owned()];
        argv.extend(peer.to_command_line());
        let back = Cli::try_parse_from(argv).expect("parses").peer;
        assert_eq!(back.to_command_line(), peer.to_command_line());
    }
}
