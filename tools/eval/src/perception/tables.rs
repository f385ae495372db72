//! The report as Markdown tables (what `harvest eval perception` prints; pasted into
//! docs/evaluation.md).

use std::fmt::Write;

use crate::perception::report::{BinReport, EstimatorReport, PerceptionReport, ScenarioReport};
use crate::perception::stats::Summary;

fn number(value: Option<f64>, decimals: usize) -> String {
    value.map_or_else(|| "-".to_owned(), |v| format!("{v:.decimals$}"))
}

fn fraction(value: Option<f64>, numerator: usize, denominator: usize) -> String {
    format!("{} ({numerator}/{denominator})", number(value, 3))
}

/// A threshold without trailing zeros (`33`, `0.9`, `38.318`).
fn compact(value: f64) -> String {
    let text = format!("{value:.3}");
    text.trim_end_matches('0').trim_end_matches('.').to_owned()
}

/// `median / p95 / max` of a summary.
fn spread(summary: &Summary, decimals: usize) -> String {
    format!(
        "{} / {} / {}",
        number(summary.median, decimals),
        number(summary.p95, decimals),
        number(summary.max, decimals)
    )
}

fn name(e: &EstimatorReport) -> String {
    format!("{} ({})", e.label(), e.role)
}

/// Renders every scenario of `report` as Markdown.
pub fn render_tables(report: &PerceptionReport) -> String {
    let mut out = String::new();
    let rule = report.matching_rule;
    // Writing into a String cannot fail.
    let _ = writeln!(
        out,
        "Perception evaluation ({} detector): {} frames per scenario (worlds seed {}..{}), {} frames without \
         apples. A reported apple matches a true apple when its box holds >= {:.0} % of \
         min(box area, apple's visible pixels) of that apple and its centre is within {} true \
         radii; pairs are assigned one to one by increasing 3D distance. \"Found in 2D\" drops the 3D \
         condition (the detector alone). Errors are Euclidean distances in the robot frame.\n",
        report.detector,
        report.frames_per_scenario,
        report.seed,
        report.seed + u64::from(report.frames_per_scenario.max(1)) - 1,
        report.empty_frames_per_scenario,
        100.0 * rule.min_overlap_coefficient,
        rule.max_distance_radii,
    );
    if let Some(seconds) = report.lidar_integration_s {
        let _ = writeln!(
            out,
            "Estimators marked `on lidar_fused` localize from one {seconds:.2} s window of the \
             simulated Mid-70 fused into the frame's depth geometry (eq. 1-2, the LiDAR's true \
             extrinsic); their times exclude the fusion (timed below). The others use the ToF \
             depth image.\n"
        );
    }
    for scenario in &report.scenarios {
        render_scenario(&mut out, scenario);
    }
    if let Some(repeatability) = &report.repeatability {
        let _ = writeln!(out, "## LiDAR-camera versus ToF (Table III)\n");
        out.push_str(&repeatability.render());
    }
    out
}

/// One table row per bin of `bins_of` (the same bins for every estimator), one cell per
/// estimator: `median / p95 / max (matched/visible)`.
fn render_bins(
    out: &mut String,
    s: &ScenarioReport,
    bins_of: impl Fn(&EstimatorReport) -> &Vec<BinReport>,
) {
    let Some(first) = s.estimators.first() else {
        return;
    };
    for (b, first_bin) in bins_of(first).iter().enumerate() {
        let mut row = format!("| {} |", first_bin.bin);
        for e in &s.estimators {
            let bin = &bins_of(e)[b];
            let _ = write!(
                row,
                " {} ({}/{}) |",
                spread(&bin.error_mm, 1),
                bin.matched,
                bin.truth_visible
            );
        }
        let _ = writeln!(out, "{row}");
    }
}

fn render_scenario(out: &mut String, s: &ScenarioReport) {
    let t = &s.truth;
    let _ = writeln!(
        out,
        "## Scenario `{}` (`--scenario {}`)\n\n{} frames: {} apples generated, {} visible (>= 1 pixel), {} at least \
         50 % visible; {} frames with 20+ visible apples; {} frames without apples. \
         Calibration: {}.\n",
        s.scenario,
        s.source,
        t.frames,
        t.apples_generated,
        t.apples_visible,
        t.apples_half_visible,
        t.frames_with_20_plus_apples,
        t.empty_frames,
        s.calibration,
    );
    let _ = writeln!(
        out,
        "### Detection\n\n| estimator | reported | true pos. | false pos. (duplicate / mislocalized / no apple) | precision | recall \
         (visible) | recall (>= 50 % visible) | same, not over-exposed | found in 2D (>= 50 % \
         visible) | reported on empty frames |\n|---|---|---|---|---|---|---|---|---|---|"
    );
    for e in &s.estimators {
        let d = &e.detection;
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} ({} / {} / {}) | {} | {} | {} | {} | {} | {} ({} of {} frames) |",
            name(e),
            d.detections,
            d.true_positives,
            d.false_positives,
            d.false_positives_duplicate,
            d.false_positives_mislocalized,
            d.false_positives_no_apple,
            number(d.precision, 3),
            fraction(d.recall, d.matched_visible, d.truth_visible),
            fraction(
                d.recall_half_visible,
                d.matched_half_visible,
                d.truth_half_visible
            ),
            number(d.recall_half_visible_not_over_exposed, 3),
            fraction(
                d.recall_2d_half_visible,
                d.found_2d_half_visible,
                d.truth_half_visible
            ),
            d.empty_frame_detections,
            d.empty_frames_with_detections,
            d.empty_frames,
        );
    }
    let _ = writeln!(
        out,
        "\n### 3D error of matched apples, mm\n\n| estimator | matched | mean | median | p95 | max |\n|---|---|---|---|---|---|"
    );
    for e in &s.estimators {
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {} | {} |",
            name(e),
            e.error_mm.count,
            number(e.error_mm.mean, 1),
            number(e.error_mm.median, 1),
            number(e.error_mm.p95, 1),
            number(e.error_mm.max, 1),
        );
    }
    let header: String = s
        .estimators
        .iter()
        .map(|e| format!(" {} |", e.label()))
        .collect();
    let rule: String = s.estimators.iter().map(|_| "---|").collect();
    let _ = writeln!(
        out,
        "\n### 3D error by depth of the true centre (colour camera z), median / p95 / max mm \
         (matched/visible)\n\n| depth, m |{header}\n|---|{rule}"
    );
    render_bins(out, s, |e| &e.error_by_depth);
    let _ = writeln!(
        out,
        "\n### 3D error by visible fraction of the silhouette, median / p95 / max mm \
         (matched/visible)\n\n| visible |{header}\n|---|{rule}"
    );
    render_bins(out, s, |e| &e.error_by_visibility);
    let _ = writeln!(
        out,
        "\n### 3D error by failure condition (from the world's ground truth; an apple can be in \
         several), median / p95 / max mm (matched/visible)\n\n| condition |{header}\n|---|{rule}"
    );
    let conditions = s
        .estimators
        .first()
        .map_or(0, |e| e.error_by_condition.len());
    for c in 0..conditions {
        let mut row = format!(
            "| {} |",
            s.estimators[0].error_by_condition[c].condition.name()
        );
        for e in &s.estimators {
            let condition = &e.error_by_condition[c];
            let _ = write!(
                row,
                " {} ({}/{}; >= 50 % visible {}/{}) |",
                spread(&condition.error_mm, 1),
                condition.matched,
                condition.truth_visible,
                condition.matched_half_visible,
                condition.truth_half_visible
            );
        }
        let _ = writeln!(out, "{row}");
    }
    let _ = writeln!(
        out,
        "\n### Processing time of `PerceptionNode::process`, one thread, ms (wall = elapsed, \
         CPU = the thread's CPU time)\n\n| estimator | frames | wall median | wall p95 | CPU median \
         | CPU p95 | CPU max | frames with 20+ apples | their CPU median | their CPU p95 |\n\
         |---|---|---|---|---|---|---|---|---|---|"
    );
    for e in &s.estimators {
        let wall = &e.timing.all_frames_ms;
        let cpu = &e.timing.all_frames_cpu_ms;
        let many = &e.timing.frames_20_plus_apples_cpu_ms;
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            name(e),
            wall.count,
            number(wall.median, 1),
            number(wall.p95, 1),
            number(cpu.median, 1),
            number(cpu.p95, 1),
            number(cpu.max, 1),
            many.count,
            number(many.median, 1),
            number(many.p95, 1),
        );
    }
    let _ = writeln!(
        out,
        "\n### Targets (reported, not asserted)\n\n| target | value | required | met |\n|---|---|---|---|"
    );
    for target in &s.targets {
        let met = match target.met {
            Some(true) => "yes",
            Some(false) => "NO",
            None => "-",
        };
        let _ = writeln!(
            out,
            "| {} | {} | {} {} | {met} |",
            target.target,
            number(target.value, 3),
            target.comparison,
            compact(target.threshold),
        );
    }
    let _ = writeln!(out);
}
