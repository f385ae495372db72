//! The plain-text tables of the laser evaluation reports (`harvest eval laser`): a heading with
//! the column names, then one row per distribution ([`Summary::columns`]).

use std::fmt::Write as _;

use super::refinement::Summary;

/// The column names after a table's title, aligned with [`Summary::columns`].
const COLUMN_NAMES: &str = "n     mean   median      p95      max";

/// Writes the heading line (`title`, then the column names), then one line per
/// `(label, summary)`: the label, then the summary's columns. Titles and labels carry their own
/// padding, which sets each table's layout.
pub fn write_summary_table(out: &mut String, title: &str, rows: &[(&str, &Summary)]) {
    // Writing into a String cannot fail.
    let _ = writeln!(out, "{title}{COLUMN_NAMES}");
    for (label, summary) in rows {
        let _ = writeln!(out, "{label}{}", summary.columns());
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_heading_then_one_row_per_summary() {
        let summary = Summary::of([1.0, 2.0, 3.0, 4.0]);
        let mut out = String::new();
        write_summary_table(&mut out, "error, mm  ", &[("ToF        ", &summary)]);
        let lines: Vec<&str> = out.lines().collect();
        assert_eq!(
            lines,
            [
                "error, mm  n     mean   median      p95      max",
                // 4 values: mean 2.5, median and p95 the nearest-rank 3rd and 4th.
                "ToF           4     2.50     3.00     4.00     4.00",
            ]
        );
    }
}
