//! The runs of one `harvest bench pipeline` side by side: the control loops' jitter with the
//! launch file's scheduling and without it, measured in one invocation on the same machine
//! under the same `--load`.

use crate::pipeline::report::{PipelineReport, millis};
use serde::Serialize;
use std::fmt::Write as _;

/// Every run of one invocation, in the order they ran.
#[derive(Debug, Clone, Serialize)]
pub struct PipelineComparison {
    pub runs: Vec<PipelineReport>,
}

impl PipelineComparison {
    /// Each run's table, then (with more than one run) the control loops' |period - 5 ms| p50,
    /// p99 and max of every run side by side, and the ratio of the last run's p99 to the
    /// first's.
    pub fn table(&self) -> String {
        let mut out = String::new();
        for run in &self.runs {
            out.push_str(&run.table());
            out.push('\n');
        }
        let [first, .., last] = self.runs.as_slice() else {
            return out;
        };
        let _ = writeln!(
            out,
            "control loops side by side: |period - 5 ms| in ms (p50 / p99 / max)\n  {:<16} {:>24} {:>24} {:>12}",
            "channel",
            short_label(first),
            short_label(last),
            "p99 ratio"
        );
        for (ours, theirs) in first.control_loop.iter().zip(&last.control_loop) {
            let cell = |jitter: &crate::pipeline::jitter::JitterResult| {
                jitter.deviation.map_or("no data".to_owned(), |d| {
                    format!(
                        "{} / {} / {}",
                        millis(d.p50_ns),
                        millis(d.p99_ns),
                        millis(d.max_ns)
                    )
                })
            };
            let ratio = match (ours.deviation, theirs.deviation) {
                (Some(a), Some(b)) if a.p99_ns > 0 => {
                    format!("{:.1}x", b.p99_ns as f64 / a.p99_ns as f64)
                }
                _ => "-".to_owned(),
            };
            let _ = writeln!(
                out,
                "  {:<16} {:>24} {:>24} {:>12}",
                ours.channel,
                cell(ours),
                cell(theirs),
                ratio
            );
        }
        out
    }
}

fn short_label(run: &PipelineReport) -> &'static str {
    use crate::pipeline::options::RunScheduling;
    match run.scheduling {
        RunScheduling::AsLaunched => "scheduled",
        RunScheduling::Without => "unscheduled",
        RunScheduling::Attached => "attached",
    }
}
