//! The latency-vs-payload-size plot, as a hand-written SVG: log-log axes, one line per
//! transport and wake-up mode through the p50 latencies, hollow markers at p99.

use crate::options::{Transport, WakeMode};
use crate::report::BenchReport;
use std::fmt::Write as _;

const WIDTH: f64 = 980.0;
const HEIGHT: f64 = 600.0;
const LEFT: f64 = 80.0;
const RIGHT: f64 = 240.0;
const TOP: f64 = 50.0;
const BOTTOM: f64 = 70.0;

fn color(transport: Transport) -> &'static str {
    match transport {
        Transport::Ours => "#1f77b4",
        Transport::Iceoryx2 => "#2ca02c",
        Transport::UdsCopy => "#d62728",
        Transport::ZenohTcp => "#ff7f0e",
        Transport::ZenohShm => "#9467bd",
        Transport::CycloneDds => "#8c564b",
    }
}

fn dash(mode: WakeMode) -> &'static str {
    match mode {
        WakeMode::Event => "",
        WakeMode::Poll => " stroke-dasharray=\"6 4\"",
    }
}

/// A marker at (x, y): circle for event mode, square for poll mode.
fn marker(out: &mut String, mode: WakeMode, x: f64, y: f64, fill: &str, stroke: &str) {
    let _ = match mode {
        WakeMode::Event => writeln!(
            out,
            "<circle cx=\"{x:.1}\" cy=\"{y:.1}\" r=\"4\" fill=\"{fill}\" stroke=\"{stroke}\" stroke-width=\"1.5\"/>"
        ),
        WakeMode::Poll => writeln!(
            out,
            "<rect x=\"{:.1}\" y=\"{:.1}\" width=\"8\" height=\"8\" fill=\"{fill}\" stroke=\"{stroke}\" stroke-width=\"1.5\"/>",
            x - 4.0,
            y - 4.0
        ),
    };
}

pub(crate) fn escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

pub(crate) fn time_label(ns: f64) -> String {
    if ns >= 1e9 {
        format!("{} s", ns / 1e9)
    } else if ns >= 1e6 {
        format!("{} ms", ns / 1e6)
    } else if ns >= 1e3 {
        format!("{} µs", ns / 1e3)
    } else {
        format!("{ns} ns")
    }
}

fn size_tick_label(bytes: f64) -> String {
    if bytes >= f64::from(1 << 20) {
        format!("{} MiB", bytes / f64::from(1 << 20))
    } else if bytes >= 1024.0 {
        format!("{} KiB", bytes / 1024.0)
    } else {
        format!("{bytes} B")
    }
}

/// Renders the plot of `report` (an empty frame if nothing was measured).
pub fn render_svg(report: &BenchReport) -> String {
    let measured: Vec<_> = report
        .results
        .iter()
        .filter_map(|r| r.latency.map(|latency| (r, latency)))
        .collect();
    let sizes = measured
        .iter()
        .map(|(r, _)| (r.size_bytes.max(1) as f64).log2());
    let x_min = sizes.clone().fold(f64::INFINITY, f64::min).min(6.0).floor();
    let x_max = sizes.fold(f64::NEG_INFINITY, f64::max).max(24.0).ceil();
    let values = measured
        .iter()
        .flat_map(|(_, l)| [l.p50_ns, l.p99_ns])
        .map(|ns| (ns.max(1) as f64).log10());
    let y_min = values
        .clone()
        .fold(f64::INFINITY, f64::min)
        .min(3.0)
        .floor();
    let y_max = values
        .fold(f64::NEG_INFINITY, f64::max)
        .max(y_min + 1.0)
        .ceil();
    let plot_w = WIDTH - LEFT - RIGHT;
    let plot_h = HEIGHT - TOP - BOTTOM;
    let x_of =
        |bytes: usize| LEFT + ((bytes.max(1) as f64).log2() - x_min) / (x_max - x_min) * plot_w;
    let y_of =
        |ns: u64| TOP + plot_h - ((ns.max(1) as f64).log10() - y_min) / (y_max - y_min) * plot_h;

    let mut out = String::new();
    let _ = writeln!(
        out,
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{WIDTH}\" height=\"{HEIGHT}\" \
viewBox=\"0 0 {WIDTH} {HEIGHT}\" font-family=\"sans-serif\" font-size=\"12\">"
    );
    let _ = writeln!(out, "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>");
    let _ = writeln!(
        out,
        "<text x=\"{LEFT}\" y=\"28\" font-size=\"15\">harvest bench ipc: one-way latency vs payload \
size (lines: p50, hollow markers: p99; median of {} runs)</text>",
        report.settings.repeats
    );
    // Decade grid and labels on the latency axis.
    for decade in (y_min as i32)..=(y_max as i32) {
        let ns = 10f64.powi(decade);
        let y = y_of(ns as u64);
        let _ = writeln!(
            out,
            "<line x1=\"{LEFT}\" y1=\"{y:.1}\" x2=\"{:.1}\" y2=\"{y:.1}\" stroke=\"#ddd\"/>",
            LEFT + plot_w
        );
        let _ = writeln!(
            out,
            "<text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"end\">{}</text>",
            LEFT - 6.0,
            y + 4.0,
            escape(&time_label(ns))
        );
    }
    // Size ticks every factor of 4.
    let mut exponent = x_min as i32 + (x_min as i32).rem_euclid(2);
    while f64::from(exponent) <= x_max {
        let bytes = 2f64.powi(exponent);
        let x = x_of(bytes as usize);
        let _ = writeln!(
            out,
            "<line x1=\"{x:.1}\" y1=\"{TOP}\" x2=\"{x:.1}\" y2=\"{:.1}\" stroke=\"#eee\"/>",
            TOP + plot_h
        );
        let _ = writeln!(
            out,
            "<text x=\"{x:.1}\" y=\"{:.1}\" text-anchor=\"middle\">{}</text>",
            TOP + plot_h + 18.0,
            escape(&size_tick_label(bytes))
        );
        exponent += 2;
    }
    let _ = writeln!(
        out,
        "<rect x=\"{LEFT}\" y=\"{TOP}\" width=\"{plot_w:.1}\" height=\"{plot_h:.1}\" fill=\"none\" stroke=\"#333\"/>"
    );
    let _ = writeln!(
        out,
        "<text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"middle\">payload size (log scale)</text>",
        LEFT + plot_w / 2.0,
        HEIGHT - 20.0
    );
    let _ = writeln!(
        out,
        "<text transform=\"translate(18 {:.1}) rotate(-90)\" text-anchor=\"middle\">one-way latency (log scale)</text>",
        TOP + plot_h / 2.0
    );

    let mut legend_y = TOP + 10.0;
    let legend_x = LEFT + plot_w + 20.0;
    for transport in Transport::ALL {
        for mode in WakeMode::ALL {
            let mut series: Vec<_> = measured
                .iter()
                .filter(|(r, _)| r.transport == transport && r.mode == mode)
                .map(|(r, l)| (r.size_bytes, *l))
                .collect();
            if series.is_empty() {
                continue;
            }
            series.sort_by_key(|(size, l)| (*size, l.p50_ns));
            let stroke = color(transport);
            let points: Vec<String> = series
                .iter()
                .map(|(size, l)| format!("{:.1},{:.1}", x_of(*size), y_of(l.p50_ns)))
                .collect();
            let _ = writeln!(
                out,
                "<polyline points=\"{}\" fill=\"none\" stroke=\"{stroke}\" stroke-width=\"2\"{}/>",
                points.join(" "),
                dash(mode)
            );
            for (size, l) in &series {
                marker(&mut out, mode, x_of(*size), y_of(l.p50_ns), stroke, stroke);
                marker(&mut out, mode, x_of(*size), y_of(l.p99_ns), "white", stroke);
            }
            let _ = writeln!(
                out,
                "<line x1=\"{legend_x:.1}\" y1=\"{legend_y:.1}\" x2=\"{:.1}\" y2=\"{legend_y:.1}\" stroke=\"{stroke}\" stroke-width=\"2\"{}/>",
                legend_x + 30.0,
                dash(mode)
            );
            marker(&mut out, mode, legend_x + 15.0, legend_y, stroke, stroke);
            let _ = writeln!(
                out,
                "<text x=\"{:.1}\" y=\"{:.1}\">{} ({})</text>",
                legend_x + 38.0,
                legend_y + 4.0,
                escape(transport.name()),
                escape(mode.name())
            );
            legend_y += 22.0;
        }
    }
    let _ = writeln!(out, "</svg>");
    out
}
