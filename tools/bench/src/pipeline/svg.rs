//! The per-hop plot of a pipeline run, as a hand-written SVG: one horizontal bar per hop and
//! end-to-end span up to its median (p50) on a logarithmic time axis, a whisker to its p99,
//! and "no data" where a hop had nothing to measure.

use crate::pipeline::report::{PipelineReport, StageResult};
use crate::svg::{escape, time_label};
use std::fmt::Write as _;

const WIDTH: f64 = 900.0;
const LEFT: f64 = 280.0;
const RIGHT: f64 = 40.0;
const TOP: f64 = 50.0;
const ROW: f64 = 30.0;
const BOTTOM: f64 = 50.0;

/// Renders the plot of `report`.
pub fn render_pipeline_svg(report: &PipelineReport) -> String {
    let rows: Vec<&StageResult> = report.hops.iter().chain(&report.end_to_end).collect();
    let height = TOP + ROW * rows.len() as f64 + BOTTOM;
    let plot_width = WIDTH - LEFT - RIGHT;
    let values: Vec<f64> = rows
        .iter()
        .filter_map(|row| row.latency)
        .flat_map(|l| [l.p50_ns as f64, l.p99_ns as f64])
        .filter(|v| *v > 0.0)
        .collect();
    // Whole decades around the data (10 us .. 1 s when there is none).
    let low = values
        .iter()
        .copied()
        .fold(f64::INFINITY, f64::min)
        .min(1e4)
        .log10()
        .floor();
    let largest = values.iter().copied().fold(0.0, f64::max);
    let high = if largest > 0.0 { largest } else { 1e9 }
        .log10()
        .ceil()
        .max(low + 1.0);
    let x_of = |ns: f64| LEFT + (ns.max(1.0).log10() - low) / (high - low) * plot_width;

    let mut out = String::new();
    let _ = writeln!(
        out,
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{WIDTH}\" height=\"{height}\" \
viewBox=\"0 0 {WIDTH} {height}\" font-family=\"sans-serif\" font-size=\"12\">"
    );
    let _ = writeln!(
        out,
        "<rect x=\"0\" y=\"0\" width=\"{WIDTH}\" height=\"{height}\" fill=\"white\"/>"
    );
    let _ = writeln!(
        out,
        "<text x=\"{}\" y=\"24\" text-anchor=\"middle\" font-size=\"15\">{}</text>",
        WIDTH / 2.0,
        escape(&format!(
            "harvest bench pipeline: latency per hop, bar p50, whisker p99 ({} CPUs)",
            report.host.cpus
        ))
    );
    let axis_y = TOP + ROW * rows.len() as f64;
    let decades = (high - low) as i32;
    for decade in 0..=decades {
        let ns = 10f64.powf(low + f64::from(decade));
        let x = x_of(ns);
        let _ = writeln!(
            out,
            "<line x1=\"{x:.1}\" y1=\"{TOP}\" x2=\"{x:.1}\" y2=\"{axis_y}\" stroke=\"#ddd\"/>"
        );
        let _ = writeln!(
            out,
            "<text x=\"{x:.1}\" y=\"{:.1}\" text-anchor=\"middle\">{}</text>",
            axis_y + 18.0,
            escape(&time_label(ns))
        );
    }
    for (index, row) in rows.iter().enumerate() {
        let y = TOP + ROW * index as f64;
        let end_to_end = index >= report.hops.len();
        let _ = writeln!(
            out,
            "<text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"end\">{}</text>",
            LEFT - 8.0,
            y + ROW / 2.0 + 4.0,
            escape(row.name.trim())
        );
        match row.latency {
            Some(latency) => {
                let x50 = x_of(latency.p50_ns as f64);
                let x99 = x_of(latency.p99_ns as f64);
                let fill = if end_to_end { "#d62728" } else { "#1f77b4" };
                let _ = writeln!(
                    out,
                    "<rect x=\"{LEFT}\" y=\"{:.1}\" width=\"{:.1}\" height=\"{:.1}\" \
fill=\"{fill}\"/>",
                    y + 6.0,
                    (x50 - LEFT).max(1.0),
                    ROW - 12.0
                );
                let mid = y + ROW / 2.0;
                let _ = writeln!(
                    out,
                    "<line x1=\"{x50:.1}\" y1=\"{mid:.1}\" x2=\"{x99:.1}\" y2=\"{mid:.1}\" \
stroke=\"black\"/>"
                );
                let _ = writeln!(
                    out,
                    "<line x1=\"{x99:.1}\" y1=\"{:.1}\" x2=\"{x99:.1}\" y2=\"{:.1}\" \
stroke=\"black\"/>",
                    mid - 5.0,
                    mid + 5.0
                );
            }
            None => {
                let _ = writeln!(
                    out,
                    "<text x=\"{:.1}\" y=\"{:.1}\" fill=\"#888\">no data</text>",
                    LEFT + 6.0,
                    y + ROW / 2.0 + 4.0
                );
            }
        }
    }
    let _ = writeln!(
        out,
        "<line x1=\"{LEFT}\" y1=\"{axis_y}\" x2=\"{:.1}\" y2=\"{axis_y}\" stroke=\"black\"/>",
        WIDTH - RIGHT
    );
    out.push_str("</svg>\n");
    out
}
