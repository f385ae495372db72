//! The benchmark report: per-case medians, side-by-side ratios, the targets, and a
//! readable table. Serialized as-is for `--json`.

use crate::case::RunResult;
use crate::options::{Settings, Transport, WakeMode};
use crate::payload_case::PayloadCase;
use crate::stats::{LatencySummary, Throughput, median_u64};
use serde::Serialize;
use std::fmt::Write as _;

/// Everything one `harvest bench ipc` run measured.
#[derive(Debug, Clone, Serialize)]
pub struct BenchReport {
    pub tool: &'static str,
    pub settings: Settings,
    pub host: HostInfo,
    /// The iceoryx2 domain the run used (removed at the end).
    pub domain: String,
    /// One entry per (payload, transport, mode), measured or not.
    pub results: Vec<CaseResult>,
    pub ratios: Vec<Ratio>,
    pub targets: Vec<TargetCheck>,
    /// Files of the run's domain still present after the run (should be empty).
    pub leftover_files: Vec<String>,
}

/// The machine the run measured.
#[derive(Debug, Clone, Serialize)]
pub struct HostInfo {
    pub cpus: usize,
    pub kernel: String,
}

/// The median numbers of one (payload, transport, mode) over the repeated runs.
#[derive(Debug, Clone, Serialize)]
pub struct CaseResult {
    pub payload: &'static str,
    pub payload_type: &'static str,
    pub size_bytes: usize,
    pub transport: Transport,
    pub mode: WakeMode,
    /// False when the transport cannot carry the payload (see `note`).
    pub measured: bool,
    pub note: Option<String>,
    /// Per-field medians over `runs`.
    pub latency: Option<LatencySummary>,
    pub producer_write_p50_ns: Option<u64>,
    /// Median over runs of the sender's median send-call time (part of the latency).
    pub sender_send_call_p50_ns: Option<u64>,
    pub throughput: Option<Throughput>,
    pub runs: Vec<RunResult>,
}

impl CaseResult {
    pub fn measured(
        payload: PayloadCase,
        transport: Transport,
        mode: WakeMode,
        runs: Vec<RunResult>,
    ) -> Self {
        let latencies: Vec<_> = runs.iter().map(|run| run.latency).collect();
        let throughputs: Vec<_> = runs.iter().map(|run| run.throughput).collect();
        Self {
            latency: LatencySummary::median_of(&latencies),
            producer_write_p50_ns: (!runs.is_empty())
                .then(|| median_u64(runs.iter().map(|run| run.producer_write_p50_ns).collect())),
            sender_send_call_p50_ns: (!runs.is_empty())
                .then(|| median_u64(runs.iter().map(|run| run.sender_send_call_p50_ns).collect())),
            throughput: Throughput::median_of(&throughputs),
            runs,
            ..Self::unmeasured(payload, transport, mode, None)
        }
    }

    pub fn unmeasured(
        payload: PayloadCase,
        transport: Transport,
        mode: WakeMode,
        note: Option<String>,
    ) -> Self {
        Self {
            payload: payload.name(),
            payload_type: payload.type_name(),
            size_bytes: payload.size_bytes(),
            transport,
            mode,
            measured: note.is_none(),
            note,
            latency: None,
            producer_write_p50_ns: None,
            sender_send_call_p50_ns: None,
            throughput: None,
            runs: Vec::new(),
        }
    }
}

/// `numerator / denominator` of two transports' median latencies, measured side by side.
#[derive(Debug, Clone, Serialize)]
pub struct Ratio {
    pub comparison: &'static str,
    pub numerator: String,
    pub denominator: String,
    pub mode: WakeMode,
    pub p50: f64,
    pub p99: f64,
}

/// One of the targets, reported (never asserted).
#[derive(Debug, Clone, Serialize)]
pub struct TargetCheck {
    pub target: &'static str,
    pub basis: String,
    pub mode: WakeMode,
    /// The measured p50 ratio.
    pub value: f64,
    pub limit: f64,
    /// Whether `value` is on the right side of `limit`.
    pub met: bool,
}

fn find(
    results: &[CaseResult],
    payload: PayloadCase,
    transport: Transport,
    mode: WakeMode,
) -> Option<(&CaseResult, LatencySummary)> {
    results
        .iter()
        .find(|r| r.payload == payload.name() && r.transport == transport && r.mode == mode)
        .and_then(|r| r.latency.map(|latency| (r, latency)))
}

fn ratio_of(a: &LatencySummary, b: &LatencySummary) -> (f64, f64) {
    let div = |x: u64, y: u64| x as f64 / y.max(1) as f64;
    (div(a.p50_ns, b.p50_ns), div(a.p99_ns, b.p99_ns))
}

fn label(result: &CaseResult) -> String {
    format!("{}@{}", result.transport.name(), result.payload)
}

/// Ratios of the compared pairs of transports measured on the same payload and mode, plus the
/// full-frame over 64 B ratio of each transport but the copying socket.
pub fn compute_ratios(results: &[CaseResult]) -> Vec<Ratio> {
    const PAIRS: [(&str, Transport, Transport); 8] = [
        ("ours / raw iceoryx2", Transport::Ours, Transport::Iceoryx2),
        ("copy / ours", Transport::UdsCopy, Transport::Ours),
        (
            "copy / raw iceoryx2",
            Transport::UdsCopy,
            Transport::Iceoryx2,
        ),
        ("zenoh-shm / ours", Transport::ZenohShm, Transport::Ours),
        ("zenoh-tcp / ours", Transport::ZenohTcp, Transport::Ours),
        (
            "zenoh-tcp / uds-copy",
            Transport::ZenohTcp,
            Transport::UdsCopy,
        ),
        ("cyclonedds / ours", Transport::CycloneDds, Transport::Ours),
        (
            "cyclonedds / uds-copy",
            Transport::CycloneDds,
            Transport::UdsCopy,
        ),
    ];
    let mut ratios = Vec::new();
    for mode in WakeMode::ALL {
        for (comparison, top, bottom) in PAIRS {
            for payload in PayloadCase::ALL {
                if let (Some((a, la)), Some((b, lb))) = (
                    find(results, payload, top, mode),
                    find(results, payload, bottom, mode),
                ) {
                    let (p50, p99) = ratio_of(&la, &lb);
                    ratios.push(Ratio {
                        comparison,
                        numerator: label(a),
                        denominator: label(b),
                        mode,
                        p50,
                        p99,
                    });
                }
            }
        }
        for transport in [
            Transport::Ours,
            Transport::Iceoryx2,
            Transport::ZenohShm,
            Transport::ZenohTcp,
            Transport::CycloneDds,
        ] {
            if let (Some((a, la)), Some((b, lb))) = (
                find(results, PayloadCase::Rgbd, transport, mode),
                find(results, PayloadCase::Bytes64, transport, mode),
            ) {
                let (p50, p99) = ratio_of(&la, &lb);
                ratios.push(Ratio {
                    comparison: "RGB-D frame / 64 B",
                    numerator: label(a),
                    denominator: label(b),
                    mode,
                    p50,
                    p99,
                });
            }
        }
    }
    ratios
}

/// The three targets, per mode, from the p50 ratios.
pub fn check_targets(results: &[CaseResult]) -> Vec<TargetCheck> {
    let mut targets = Vec::new();
    for mode in WakeMode::ALL {
        let mut add = |target: &'static str,
                       numerator: (PayloadCase, Transport),
                       denominator: (PayloadCase, Transport),
                       limit: f64,
                       at_most: bool| {
            if let (Some((a, la)), Some((b, lb))) = (
                find(results, numerator.0, numerator.1, mode),
                find(results, denominator.0, denominator.1, mode),
            ) {
                let (value, _) = ratio_of(&la, &lb);
                targets.push(TargetCheck {
                    target,
                    basis: format!("p50 {} / p50 {}", label(a), label(b)),
                    mode,
                    value,
                    limit,
                    met: if at_most {
                        value <= limit
                    } else {
                        value >= limit
                    },
                });
            }
        };
        add(
            "zero-copy RGB-D frame latency within 2x of 64 B",
            (PayloadCase::Rgbd, Transport::Ours),
            (PayloadCase::Bytes64, Transport::Ours),
            2.0,
            true,
        );
        add(
            "8 MB: copying baseline at least 100x slower than our layer",
            (PayloadCase::MiB8, Transport::UdsCopy),
            (PayloadCase::MiB8, Transport::Ours),
            100.0,
            false,
        );
        add(
            "RGB-D frame (6.8 MB): copying baseline at least 100x slower than our layer",
            (PayloadCase::Rgbd, Transport::UdsCopy),
            (PayloadCase::Rgbd, Transport::Ours),
            100.0,
            false,
        );
        for payload in [
            PayloadCase::Bytes64,
            PayloadCase::ScanRequest,
            PayloadCase::Detections,
            PayloadCase::Rgbd,
            PayloadCase::MiB8,
        ] {
            add(
                "our layer adds at most 20 % over raw iceoryx2",
                (payload, Transport::Ours),
                (payload, Transport::Iceoryx2),
                1.2,
                true,
            );
        }
    }
    targets
}

/// Formats nanoseconds as microseconds with 3 significant-ish digits.
fn micros(ns: u64) -> String {
    let us = ns as f64 / 1000.0;
    if us < 10.0 {
        format!("{us:.2}")
    } else if us < 100.0 {
        format!("{us:.1}")
    } else {
        format!("{us:.0}")
    }
}

fn size_label(bytes: usize) -> String {
    if bytes >= 1 << 20 {
        format!("{:.1} MiB", bytes as f64 / f64::from(1 << 20))
    } else if bytes >= 1 << 10 {
        format!("{:.1} KiB", bytes as f64 / 1024.0)
    } else {
        format!("{bytes} B")
    }
}

impl BenchReport {
    /// The readable table: latencies in microseconds (medians over the runs), throughput,
    /// ratios and targets.
    pub fn table(&self) -> String {
        let mut out = String::new();
        let s = &self.settings;
        let _ = writeln!(
            out,
            "harvest bench ipc: one-way latency, {} runs per case (median), {} iterations, \
{} warm-up, {:.1} s limit, {} CPUs{}, sender writes: {}{}",
            s.repeats,
            s.iterations,
            s.warmup,
            s.duration.as_secs_f64(),
            self.host.cpus,
            match s.pin_cpus {
                Some((receiver, sender)) =>
                    format!(", receiver on CPU {receiver}, sender on CPU {sender}"),
                None => String::new(),
            },
            s.sender_write.name(),
            match s.sender_write {
                crate::sender_write::SenderWrite::Full => " (fair test)",
                _ => " (diagnostic variant, not the fair test)",
            }
        );
        let _ = writeln!(
            out,
            "{:<13} {:>10} {:<6} {:<9} {:>6} {:>9} {:>9} {:>9} {:>9} {:>9} {:>11} {:>9} {:>7} {:>9} {:>9}",
            "payload",
            "size",
            "mode",
            "transport",
            "n",
            "p50 us",
            "p90 us",
            "p99 us",
            "p99.9 us",
            "max us",
            "msg/s",
            "MB/s",
            "drops",
            "write us",
            "send us"
        );
        for result in self.results.iter().filter(|r| r.measured) {
            let (Some(l), Some(t)) = (result.latency, result.throughput) else {
                continue;
            };
            let _ = writeln!(
                out,
                "{:<13} {:>10} {:<6} {:<9} {:>6} {:>9} {:>9} {:>9} {:>9} {:>9} {:>11.0} {:>9.1} {:>7} {:>9} {:>9}",
                result.payload,
                size_label(result.size_bytes),
                result.mode.name(),
                result.transport.name(),
                l.samples,
                micros(l.p50_ns),
                micros(l.p90_ns),
                micros(l.p99_ns),
                micros(l.p999_ns),
                micros(l.max_ns),
                t.msgs_per_s,
                t.mb_per_s,
                t.dropped,
                micros(result.producer_write_p50_ns.unwrap_or(0)),
                micros(result.sender_send_call_p50_ns.unwrap_or(0)),
            );
        }
        let _ = writeln!(
            out,
            "write us: the sender writing the payload before publish_ns (not in the latency); \
send us: the sender's send call after publish_ns (the sender's share of the latency)"
        );
        let mut notes: Vec<_> = self
            .results
            .iter()
            .filter_map(|r| r.note.as_ref().map(|note| (r.transport.name(), note)))
            .collect();
        notes.dedup();
        for (transport, note) in notes {
            let _ = writeln!(out, "note ({transport}): {note}");
        }
        let _ = writeln!(out, "\nratios (measured side by side, same run):");
        for ratio in &self.ratios {
            let _ = writeln!(
                out,
                "  {:<20} {:<5} {:>22} / {:<22} p50 {:>8.2}x  p99 {:>8.2}x",
                ratio.comparison,
                ratio.mode.name(),
                ratio.numerator,
                ratio.denominator,
                ratio.p50,
                ratio.p99
            );
        }
        let _ = writeln!(out, "\ntargets (reported, not asserted):");
        for target in &self.targets {
            let _ = writeln!(
                out,
                "  [{}] {} ({}): {:.2} vs {} {} ({})",
                if target.met { "met" } else { "MISSED" },
                target.target,
                target.mode.name(),
                target.value,
                if target.limit >= 100.0 { ">=" } else { "<=" },
                target.limit,
                target.basis
            );
        }
        if !self.leftover_files.is_empty() {
            let _ = writeln!(
                out,
                "\nleftover iceoryx2 files: {}",
                self.leftover_files.join(", ")
            );
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(p50_ns: u64) -> RunResult {
        RunResult {
            latency: LatencySummary {
                samples: 100,
                p50_ns,
                p90_ns: p50_ns,
                p99_ns: 2 * p50_ns,
                p999_ns: 2 * p50_ns,
                max_ns: 3 * p50_ns,
                mean_ns: p50_ns as f64,
            },
            producer_write_p50_ns: 5,
            sender_send_call_p50_ns: 2,
            throughput: Throughput {
                msgs_per_s: 10.0,
                mb_per_s: 1.0,
                received: 10,
                dropped: 0,
            },
        }
    }

    #[test]
    fn ratios_and_targets_from_known_latencies() {
        let mode = WakeMode::Event;
        let results = vec![
            CaseResult::measured(PayloadCase::Bytes64, Transport::Ours, mode, vec![run(1000)]),
            CaseResult::measured(
                PayloadCase::ScanRequest,
                Transport::Ours,
                mode,
                vec![run(1000)],
            ),
            CaseResult::measured(
                PayloadCase::ScanRequest,
                Transport::Iceoryx2,
                mode,
                vec![run(900)],
            ),
            CaseResult::measured(PayloadCase::Rgbd, Transport::Ours, mode, vec![run(1500)]),
            CaseResult::measured(
                PayloadCase::Rgbd,
                Transport::Iceoryx2,
                mode,
                vec![run(1400)],
            ),
            CaseResult::measured(
                PayloadCase::Rgbd,
                Transport::UdsCopy,
                mode,
                vec![run(3_000_000)],
            ),
            CaseResult::measured(
                PayloadCase::Bytes64,
                Transport::ZenohShm,
                mode,
                vec![run(2000)],
            ),
            CaseResult::measured(
                PayloadCase::Rgbd,
                Transport::ZenohShm,
                mode,
                vec![run(3000)],
            ),
            CaseResult::measured(
                PayloadCase::Rgbd,
                Transport::ZenohTcp,
                mode,
                vec![run(6_000_000)],
            ),
            CaseResult::unmeasured(PayloadCase::MiB8, Transport::Ours, mode, Some("n/a".into())),
        ];
        let ratios = compute_ratios(&results);
        let find_ratio = |comparison: &str, numerator: &str| {
            ratios
                .iter()
                .find(|r| r.comparison == comparison && r.numerator == numerator)
                .map(|r| r.p50)
        };
        let ours_over_raw = find_ratio("ours / raw iceoryx2", "ours@scan-request").expect("ratio");
        assert!((ours_over_raw - 1000.0 / 900.0).abs() < 1e-12);
        assert_eq!(find_ratio("copy / ours", "uds-copy@rgbd"), Some(2000.0));
        assert_eq!(find_ratio("RGB-D frame / 64 B", "ours@rgbd"), Some(1.5));
        assert_eq!(
            find_ratio("zenoh-shm / ours", "zenoh-shm@rgbd"),
            Some(3000.0 / 1500.0)
        );
        assert_eq!(
            find_ratio("zenoh-tcp / uds-copy", "zenoh-tcp@rgbd"),
            Some(6_000_000.0 / 3_000_000.0)
        );
        assert_eq!(
            find_ratio("RGB-D frame / 64 B", "zenoh-shm@rgbd"),
            Some(3000.0 / 2000.0)
        );

        let targets = check_targets(&results);
        let frame = targets
            .iter()
            .find(|t| t.target.starts_with("zero-copy"))
            .expect("target");
        assert!(frame.met && (frame.value - 1.5).abs() < 1e-12);
        let copy = targets
            .iter()
            .find(|t| t.target.starts_with("RGB-D frame"))
            .expect("target");
        assert!(copy.met && copy.value == 2000.0);
        let overhead: Vec<_> = targets
            .iter()
            .filter(|t| t.target.starts_with("our layer"))
            .collect();
        assert_eq!(overhead.len(), 2, "detections was not measured");
        assert!(overhead.iter().all(|t| t.met));
        // No 8 MiB zero-copy result: that target is absent, not failed.
        assert!(!targets.iter().any(|t| t.target.starts_with("8 MB")));
    }

    #[test]
    fn medians_over_runs() {
        let result = CaseResult::measured(
            PayloadCase::KiB1,
            Transport::Iceoryx2,
            WakeMode::Poll,
            vec![run(300), run(100), run(200)],
        );
        assert!(result.measured);
        assert_eq!(result.latency.expect("latency").p50_ns, 200);
        assert_eq!(result.runs.len(), 3);
    }
}
