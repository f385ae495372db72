//! The pipeline report: per-hop and end-to-end latencies, control-loop jitter, what each
//! channel delivered, and a readable table. Serialized as-is for `--json`.

use crate::pipeline::jitter::JitterResult;
use crate::pipeline::options::{PipelineSettings, RunScheduling};
use crate::pipeline::summary::Summary;
use crate::pipeline::tracker::Stage;
use crate::report::HostInfo;
use serde::Serialize;
use std::fmt::Write as _;

/// Everything one `harvest bench pipeline` run measured.
#[derive(Debug, Clone, Serialize)]
pub struct PipelineReport {
    pub tool: &'static str,
    pub settings: PipelineSettings,
    /// The scheduling of the processes in this run.
    pub scheduling: RunScheduling,
    pub host: HostInfo,
    /// The domain measured (the bench's own unless --attach).
    pub domain: String,
    /// True when SIGINT/SIGTERM ended collection early.
    pub interrupted: bool,
    /// Per-hop latencies, in pipeline order.
    pub hops: Vec<StageResult>,
    /// End-to-end latencies.
    pub end_to_end: Vec<StageResult>,
    /// Period jitter of `armN/command`, `armN/state` and `vacuum/state` (nominal 5 ms).
    pub control_loop: Vec<JitterResult>,
    /// What the bench received per channel while collecting.
    pub channels: Vec<ChannelResult>,
    /// The stack's log (supervisor and process output), when the bench started the stack.
    pub stack_log: Option<String>,
    /// Files of the bench's own domain left after the stack stopped (should be empty).
    pub leftover_files: Vec<String>,
}

/// One hop or end-to-end span.
#[derive(Debug, Clone, Serialize)]
pub struct StageResult {
    pub stage: Stage,
    pub name: &'static str,
    /// None: no data (see `note`).
    pub latency: Option<Summary>,
    /// Set when there is no data: which channels carried nothing to match.
    pub note: Option<String>,
}

impl StageResult {
    pub fn new(stage: Stage, latency: Option<Summary>) -> Self {
        let note = latency
            .is_none()
            .then(|| format!("no data: no matched messages on {}", stage.channels()));
        Self {
            stage,
            name: stage.name(),
            latency,
            note,
        }
    }
}

/// What one subscription saw while collecting.
#[derive(Debug, Clone, Serialize)]
pub struct ChannelResult {
    pub topic: &'static str,
    pub received: u64,
    /// Messages per second from the first to the last `publish_ns` received.
    pub rate_hz: f64,
    /// Messages the bench's subscriber lost (overwritten in its buffer) while collecting.
    pub dropped: u64,
    /// One-way delivery to the bench: receive time - `publish_ns` (includes the bench's own
    /// wake-up on a loaded machine).
    pub delivery: Option<Summary>,
}

pub(crate) fn millis(ns: u64) -> String {
    let ms = ns as f64 / 1e6;
    if ms < 1.0 {
        format!("{ms:.3}")
    } else if ms < 100.0 {
        format!("{ms:.2}")
    } else {
        format!("{ms:.0}")
    }
}

fn write_stage_row(out: &mut String, result: &StageResult) {
    match &result.latency {
        Some(l) => {
            let _ = writeln!(
                out,
                "  {:<36} {:>6} {:>9} {:>9} {:>9} {:>9}",
                result.name,
                l.samples,
                millis(l.p50_ns),
                millis(l.p90_ns),
                millis(l.p99_ns),
                millis(l.max_ns)
            );
        }
        None => {
            let _ = writeln!(
                out,
                "  {:<36} {:>6} {}",
                result.name,
                0,
                result.note.as_deref().unwrap_or("no data")
            );
        }
    }
}

impl PipelineReport {
    /// The readable table: latencies in milliseconds (p50 is the median of the run).
    pub fn table(&self) -> String {
        let mut out = String::new();
        let s = &self.settings;
        let _ = writeln!(
            out,
            "harvest bench pipeline, {}: {:.1} s collected after {:.1} s warm-up, domain {}, {} \
CPUs, {} extra busy threads{}{}",
            self.scheduling.label(),
            s.duration.as_secs_f64(),
            s.warmup.as_secs_f64(),
            self.domain,
            self.host.cpus,
            s.load_threads,
            match &s.launch {
                Some(launch) => format!(", launch {launch}"),
                None => ", attached to a running stack".to_owned(),
            },
            if self.interrupted {
                " (interrupted)"
            } else {
                ""
            }
        );
        let header = format!(
            "  {:<36} {:>6} {:>9} {:>9} {:>9} {:>9}",
            "hop", "n", "p50 ms", "p90 ms", "p99 ms", "max ms"
        );
        let _ = writeln!(out, "\nper hop (from message headers):\n{header}");
        for result in &self.hops {
            write_stage_row(&mut out, result);
        }
        let _ = writeln!(out, "\nend to end:\n{header}");
        for result in &self.end_to_end {
            write_stage_row(&mut out, result);
        }
        let _ = writeln!(
            out,
            "\n200 Hz control loops (arms, vacuum; nominal 5 ms): |period - 5 ms|\n  {:<36} {:>6} {:>10} \
{:>9} {:>9} {:>9} {:>6}",
            "channel", "n", "period p50", "dev p50", "dev p99", "dev max", "gaps"
        );
        for jitter in &self.control_loop {
            match (&jitter.period, &jitter.deviation) {
                (Some(period), Some(deviation)) => {
                    let _ = writeln!(
                        out,
                        "  {:<36} {:>6} {:>10} {:>9} {:>9} {:>9} {:>6}",
                        jitter.channel,
                        jitter.periods,
                        millis(period.p50_ns),
                        millis(deviation.p50_ns),
                        millis(deviation.p99_ns),
                        millis(deviation.max_ns),
                        jitter.gaps
                    );
                }
                _ => {
                    let _ = writeln!(
                        out,
                        "  {:<36} {:>6} no data: no consecutive messages",
                        jitter.channel, 0
                    );
                }
            }
        }
        let _ = writeln!(
            out,
            "\nchannels (as received by the bench):\n  {:<20} {:>8} {:>8} {:>8} {:>14} {:>14}",
            "topic", "received", "rate Hz", "dropped", "delivery p50", "delivery p99"
        );
        for channel in &self.channels {
            let (p50, p99) = channel
                .delivery
                .map_or(("-".to_owned(), "-".to_owned()), |d| {
                    (
                        format!("{} ms", millis(d.p50_ns)),
                        format!("{} ms", millis(d.p99_ns)),
                    )
                });
            let _ = writeln!(
                out,
                "  {:<20} {:>8} {:>8.1} {:>8} {:>14} {:>14}",
                channel.topic, channel.received, channel.rate_hz, channel.dropped, p50, p99
            );
        }
        if let Some(log) = &self.stack_log {
            let _ = writeln!(out, "\nstack log: {log}");
        }
        if !self.leftover_files.is_empty() {
            let _ = writeln!(
                out,
                "leftover iceoryx2 files: {}",
                self.leftover_files.join(", ")
            );
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pipeline::jitter::PeriodTracker;
    use std::time::Duration;

    fn summary(p50_ns: u64) -> Summary {
        Summary {
            samples: 10,
            p50_ns,
            p90_ns: p50_ns,
            p99_ns: 2 * p50_ns,
            max_ns: 3 * p50_ns,
            mean_ns: p50_ns as f64,
        }
    }

    #[test]
    fn table_shows_numbers_and_no_data() {
        let report = PipelineReport {
            tool: "harvest bench pipeline",
            settings: PipelineSettings {
                duration: Duration::from_secs(2),
                warmup: Duration::from_secs(1),
                launch: None,
                attached: true,
                load_threads: 0,
            },
            scheduling: RunScheduling::Attached,
            host: HostInfo {
                cpus: 2,
                kernel: "test".to_owned(),
            },
            domain: "d".to_owned(),
            interrupted: false,
            hops: vec![
                StageResult::new(Stage::CameraPublish, Some(summary(4_250_000))),
                StageResult::new(Stage::ArmCommand, None),
            ],
            end_to_end: vec![StageResult::new(Stage::CaptureToCommand, None)],
            control_loop: vec![PeriodTracker::default().result("arm1/command")],
            channels: vec![ChannelResult {
                topic: "camera/rgbd",
                received: 60,
                rate_hz: 30.0,
                dropped: 0,
                delivery: Some(summary(20_000)),
            }],
            stack_log: None,
            leftover_files: Vec::new(),
        };
        let table = report.table();
        assert!(table.contains("capture -> camera/rgbd"), "{table}");
        assert!(table.contains("4.25"), "{table}");
        assert!(table.contains("no data: no matched messages on armN/target"));
        assert!(table.contains("0.020 ms"), "{table}");
        let json = serde_json::to_value(&report).expect("serializes");
        assert_eq!(json["hops"][0]["stage"], "camera-publish");
        assert_eq!(json["hops"][0]["latency"]["p50_ns"], 4_250_000);
        assert!(json["hops"][1]["latency"].is_null());
        assert!(json["control_loop"][0]["deviation"].is_null());
    }
}
