//! Row scenarios: an orchard row of several tree sections, the platform's travel and the
//! tractor that pulls the robot's trailer along the row ([dual-arm sec. 2.2 and 4.1]: the
//! robot harvests stop and go along a row).
//!
//! A row file is TOML (unknown keys rejected):
//!
//! ```toml
//! name = "two_sections"
//! description = "Two fruiting-wall sections"
//!
//! [platform]            # the stages' stops in the row frame, m (see below)
//! in_out_range_m = [0.0, 0.5]
//! up_down_range_m = [0.0, 0.8]
//!
//! [tractor]
//! speed_m_per_s = 0.3   # advance speed along the row
//! start_m = 0.0         # trailer position at the start of the row
//!
//! [placement]           # optional; where each section stands from the tractor's path
//! canopy_setback_m = [0.15, 0.40]    # canopy this much farther than its preset, per section
//! fruiting_zone_lift_m = [0.1, 0.5]  # fruiting zone this much higher than its preset
//!
//! [[section]]
//! canopy = "default"    # a scenario preset (`crate::scenario::preset_names`)
//! center_m = 0.0        # where the section's y = 0 lies along the row, m
//! seed = 11             # optional; default: the world seed + the section's index
//! ```
//!
//! Frames: the row frame is the robot frame when the trailer stands at 0 m along the row and
//! both stages stand at 0 (x toward the canopy, y along the row, z up). A section occupies
//! `center_m + canopy.y_range_m` of its preset along the row; sections may not overlap. A
//! stage's range `[min, max]` is where its stops put the robot in the row frame: the stage's
//! travel is `max - min` (the platform device's `[0, max - min]`), and the robot's offset on
//! that axis is `min + stage position`. The camera, background, lighting, vacuum and failure
//! rates of the row are those of the first section's preset.
//!
//! Placement ([dual-arm sec. 4.1]: the tractor halts, then the platform moves the robot in
//! and up "so that the dropping module makes contact with the canopy"). A preset puts its
//! canopy where the arms reach best with the stages at their stops; in a row the tractor's
//! path keeps a clearance from the canopy that varies along the row, and so does the height
//! of the fruiting zone. Each section is therefore moved away from the robot (row-frame x)
//! by a setback and up (z) by a lift, both drawn uniformly from the `[placement]` ranges with
//! the section's seed ([`RowScenario::section_placement_m`]). Absent, both are 0 (every
//! section exactly where its preset puts it).

use crate::scenario::{
    InvalidValue, Scenario, ScenarioError, SourceLocation, line_column, parse_error,
};
use harvest_hw::platform::PlatformTravel;
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use toml::de::{DeTable, DeValue};

/// One tree section of the row.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RowSection {
    /// Scenario preset giving the canopy kind, apples and foliage of the section.
    pub canopy: String,
    /// Position along the row of the preset's y = 0, m.
    pub center_m: f64,
    /// Generation seed of the section; default: the world seed plus the section's index.
    #[serde(default)]
    pub seed: Option<u64>,
}

/// Where the platform's stages put the robot in the row frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RowPlatform {
    /// In-out stops `[min, max]`, m along row-frame x.
    pub in_out_range_m: [f64; 2],
    /// Up-down stops `[min, max]`, m along row-frame z.
    pub up_down_range_m: [f64; 2],
}

impl Default for RowPlatform {
    fn default() -> Self {
        let travel = PlatformTravel::default();
        Self {
            in_out_range_m: [0.0, travel.in_out_max_m],
            up_down_range_m: [0.0, travel.up_down_max_m],
        }
    }
}

impl RowPlatform {
    /// The stages' travel (`max - min` of each range).
    pub fn travel(&self) -> PlatformTravel {
        PlatformTravel {
            in_out_max_m: self.in_out_range_m[1] - self.in_out_range_m[0],
            up_down_max_m: self.up_down_range_m[1] - self.up_down_range_m[0],
        }
    }

    /// Row-frame offset `[x, z]` of the robot for stage positions `[in_out, up_down]`.
    pub fn offset_m(&self, stage_m: [f64; 2]) -> [f64; 2] {
        [
            self.in_out_range_m[0] + stage_m[0],
            self.up_down_range_m[0] + stage_m[1],
        ]
    }
}

/// The tractor pulling the trailer.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RowTractor {
    /// Advance speed along the row, m/s (choice: 0.3 m/s, an orchard tractor in creeper gear).
    pub speed_m_per_s: f64,
    /// Trailer position along the row at the start, m.
    pub start_m: f64,
}

impl Default for RowTractor {
    fn default() -> Self {
        Self {
            speed_m_per_s: 0.3,
            start_m: 0.0,
        }
    }
}

/// How far each section stands from where its preset puts it (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RowPlacement {
    /// Range `[min, max]` of the extra distance of a section's canopy from the robot at the
    /// in-out stop (row-frame x), m.
    #[serde(default)]
    pub canopy_setback_m: [f64; 2],
    /// Range `[min, max]` of the extra height of a section's fruiting zone (row-frame z), m.
    #[serde(default)]
    pub fruiting_zone_lift_m: [f64; 2],
}

/// Largest accepted magnitude of a placement value, m (beyond it a section leaves any
/// platform's travel: a typing error, not an orchard).
pub const MAX_PLACEMENT_M: f64 = 1.0;

/// A whole row as written in its file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RowFile {
    pub name: String,
    #[serde(default)]
    pub description: String,
    #[serde(default)]
    pub platform: RowPlatform,
    #[serde(default)]
    pub tractor: RowTractor,
    #[serde(default)]
    pub placement: RowPlacement,
    /// The sections, in any order (sorted along the row when loaded).
    #[serde(rename = "section")]
    pub sections: Vec<RowSection>,
}

/// A loaded, validated row: the file and each section's scenario, sorted along the row.
#[derive(Debug, Clone, PartialEq)]
pub struct RowScenario {
    /// Where it was read from (file path).
    pub origin: String,
    pub file: RowFile,
    /// Per section (same order as `file.sections`, sorted by `center_m`): its scenario.
    pub scenarios: Vec<Scenario>,
}

/// Why a row file could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum RowError {
    #[error("cannot read row file {path}: {source}")]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    /// Not TOML, unknown / missing keys, wrong types (origin, line, column and key named).
    #[error(transparent)]
    Parse(ScenarioError),
    /// A value or the geometry is impossible (origin, line and key named).
    #[error(transparent)]
    Invalid(Box<InvalidValue>),
}

/// One step of a key path: a table key or an array element.
#[derive(Debug, Clone, Copy, PartialEq)]
enum KeyStep {
    Key(&'static str),
    Index(usize),
}

impl RowScenario {
    /// Loads and validates a row file.
    pub fn from_file(path: &Path) -> Result<Self, RowError> {
        let text = std::fs::read_to_string(path).map_err(|source| RowError::Read {
            path: path.to_owned(),
            source,
        })?;
        Self::from_toml_str(&path.display().to_string(), &text)
    }

    /// Parses and validates row text; `origin` names the source in errors.
    pub fn from_toml_str(origin: &str, text: &str) -> Result<Self, RowError> {
        let mut file: RowFile = toml::from_str(text)
            .map_err(|error| RowError::Parse(parse_error(origin, text, &error)))?;
        let invalid = |path: &[KeyStep], value: String, reason: String| {
            let (line, column) =
                locate(text, path).map_or((None, None), |(l, c)| (Some(l), Some(c)));
            RowError::Invalid(Box::new(InvalidValue {
                location: SourceLocation {
                    origin: origin.to_owned(),
                    line,
                    column,
                },
                key: key_name(path),
                value,
                reason,
            }))
        };
        use KeyStep::{Index, Key};
        for (key, range) in [
            ("in_out_range_m", file.platform.in_out_range_m),
            ("up_down_range_m", file.platform.up_down_range_m),
        ] {
            if !(range[0].is_finite() && range[1].is_finite() && range[0] < range[1]) {
                return Err(invalid(
                    &[Key("platform"), Key(key)],
                    format!("{range:?}"),
                    "must be finite [min, max] with min < max".to_owned(),
                ));
            }
        }
        let speed = file.tractor.speed_m_per_s;
        if !(speed.is_finite() && speed > 0.0) {
            return Err(invalid(
                &[Key("tractor"), Key("speed_m_per_s")],
                speed.to_string(),
                "must be finite and > 0".to_owned(),
            ));
        }
        if !file.tractor.start_m.is_finite() {
            return Err(invalid(
                &[Key("tractor"), Key("start_m")],
                file.tractor.start_m.to_string(),
                "must be finite".to_owned(),
            ));
        }
        for (key, range) in [
            ("canopy_setback_m", file.placement.canopy_setback_m),
            ("fruiting_zone_lift_m", file.placement.fruiting_zone_lift_m),
        ] {
            let bounded = range
                .iter()
                .all(|value| value.is_finite() && value.abs() <= MAX_PLACEMENT_M);
            if !(bounded && range[0] <= range[1]) {
                return Err(invalid(
                    &[Key("placement"), Key(key)],
                    format!("{range:?}"),
                    format!(
                        "must be finite [min, max] with min <= max, each within \
                         +-{MAX_PLACEMENT_M} m"
                    ),
                ));
            }
        }
        if file.sections.is_empty() {
            return Err(invalid(
                &[Key("section")],
                "[]".to_owned(),
                "a row needs at least one [[section]]".to_owned(),
            ));
        }
        // Validate each section in file order (so the line is the section's own).
        let mut placed = Vec::with_capacity(file.sections.len());
        for (index, section) in file.sections.iter().enumerate() {
            if !section.center_m.is_finite() {
                return Err(invalid(
                    &[Key("section"), Index(index), Key("center_m")],
                    section.center_m.to_string(),
                    "must be finite".to_owned(),
                ));
            }
            let scenario = Scenario::preset(&section.canopy).map_err(|error| {
                invalid(
                    &[Key("section"), Index(index), Key("canopy")],
                    format!("{:?}", section.canopy),
                    error.to_string(),
                )
            })?;
            let canopy_back_m = scenario.canopy.front_x_m
                + scenario.canopy.depth_m
                + file.placement.canopy_setback_m[1];
            if canopy_back_m >= scenario.background.next_row_x_m {
                return Err(invalid(
                    &[Key("placement"), Key("canopy_setback_m")],
                    format!("{:?}", file.placement.canopy_setback_m),
                    format!(
                        "section {} ({}) would reach {canopy_back_m:.3} m, into the next row \
                         at {:.3} m",
                        index + 1,
                        section.canopy,
                        scenario.background.next_row_x_m
                    ),
                ));
            }
            let y = scenario.canopy.y_range_m;
            placed.push((
                index,
                section.center_m + y[0],
                section.center_m + y[1],
                scenario,
            ));
        }
        placed.sort_by(|a, b| a.1.total_cmp(&b.1));
        for pair in placed.windows(2) {
            let (earlier, later) = (&pair[0], &pair[1]);
            if later.1 < earlier.2 {
                let (index, other) = (later.0.max(earlier.0), later.0.min(earlier.0));
                return Err(invalid(
                    &[Key("section"), Index(index), Key("center_m")],
                    file.sections[index].center_m.to_string(),
                    format!(
                        "section {} ([{:.3}, {:.3}] m along the row) overlaps section {} \
                         ([{:.3}, {:.3}] m)",
                        index + 1,
                        if index == later.0 { later.1 } else { earlier.1 },
                        if index == later.0 { later.2 } else { earlier.2 },
                        other + 1,
                        if index == later.0 { earlier.1 } else { later.1 },
                        if index == later.0 { earlier.2 } else { later.2 },
                    ),
                ));
            }
        }
        let order: Vec<usize> = placed.iter().map(|entry| entry.0).collect();
        let sections = order.iter().map(|&i| file.sections[i].clone()).collect();
        file.sections = sections;
        Ok(Self {
            origin: origin.to_owned(),
            file,
            scenarios: placed.into_iter().map(|entry| entry.3).collect(),
        })
    }

    /// Seed of section `index` (sorted order) in a world seeded with `seed`.
    pub fn section_seed(&self, index: usize, seed: u64) -> u64 {
        self.file.sections[index]
            .seed
            .unwrap_or_else(|| seed.wrapping_add(index as u64))
    }

    /// Setback and lift `[x, z]` of section `index` (sorted order) in a world seeded with
    /// `seed`, m: drawn uniformly from the `[placement]` ranges with the section's seed.
    pub fn section_placement_m(&self, index: usize, seed: u64) -> [f64; 2] {
        // A stream of its own (not the section's generation stream), so that the apples of a
        // section stay the same whatever its placement.
        const PLACEMENT_STREAM: u64 = 0x706c_6163_656d_656e;
        let mut rng = SmallRng::seed_from_u64(self.section_seed(index, seed) ^ PLACEMENT_STREAM);
        let placement = &self.file.placement;
        [placement.canopy_setback_m, placement.fruiting_zone_lift_m].map(|range| {
            if range[1] > range[0] {
                rng.random_range(range[0]..range[1])
            } else {
                range[0]
            }
        })
    }

    /// Along-row extent `[start, end]` of the whole row (first section's start to the last's
    /// end), m.
    pub fn extent_m(&self) -> [f64; 2] {
        let first = &self.file.sections[0];
        let last_index = self.file.sections.len() - 1;
        let last = &self.file.sections[last_index];
        [
            first.center_m + self.scenarios[0].canopy.y_range_m[0],
            last.center_m + self.scenarios[last_index].canopy.y_range_m[1],
        ]
    }
}

/// Dotted key with 1-based section numbers (`section[2].center_m`).
fn key_name(path: &[KeyStep]) -> String {
    let mut name = String::new();
    for step in path {
        match step {
            KeyStep::Key(key) => {
                if !name.is_empty() {
                    name.push('.');
                }
                name.push_str(key);
            }
            KeyStep::Index(index) => name.push_str(&format!("[{}]", index + 1)),
        }
    }
    name
}

/// Line and column of the deepest step of `path` present in the document.
fn locate(text: &str, path: &[KeyStep]) -> Option<(usize, usize)> {
    let document = DeTable::parse(text).ok()?;
    let mut value: Option<&DeValue<'_>> = None;
    let mut table: Option<&DeTable<'_>> = Some(document.get_ref());
    let mut found = None;
    for step in path {
        match *step {
            KeyStep::Key(key) => {
                let (name, inner) = table?.iter().find(|(name, _)| name.get_ref() == key)?;
                found = Some(line_column(text, name.span().start));
                value = Some(inner.get_ref());
            }
            KeyStep::Index(index) => {
                let Some(DeValue::Array(items)) = value else {
                    return found;
                };
                let item = items.get(index)?;
                found = Some(line_column(text, item.span().start));
                value = Some(item.get_ref());
            }
        }
        table = match value {
            Some(DeValue::Table(inner)) => Some(inner),
            _ => None,
        };
    }
    found
}

#[cfg(test)]
mod tests {
    use super::*;

    const TWO_SECTIONS: &str = r#"name = "two"

[platform]
in_out_range_m = [0.0, 0.5]
up_down_range_m = [0.0, 0.8]

[[section]]
canopy = "default"
center_m = 0.0

[[section]]
canopy = "gala_vertical_wall"
center_m = 2.0
"#;

    fn invalid(text: &str) -> InvalidValue {
        match RowScenario::from_toml_str("rows/test.toml", text) {
            Err(RowError::Invalid(problem)) => *problem,
            other => panic!("expected an invalid value, got {other:?}"),
        }
    }

    #[test]
    fn a_valid_row_loads_sorted_along_the_row() {
        let text = TWO_SECTIONS.replace("center_m = 0.0", "center_m = 4.0");
        let row = RowScenario::from_toml_str("rows/test.toml", &text).expect("row");
        assert_eq!(row.file.sections[0].center_m, 2.0);
        assert_eq!(row.file.sections[1].center_m, 4.0);
        assert_eq!(row.scenarios.len(), 2);
        assert_eq!(row.section_seed(1, 10), 11);
        assert!(row.extent_m()[0] < 2.0 && row.extent_m()[1] > 4.0);
    }

    #[test]
    fn overlapping_sections_name_file_line_and_key() {
        let text = TWO_SECTIONS.replace("center_m = 2.0", "center_m = 1.0");
        let problem = invalid(&text);
        assert_eq!(problem.key, "section[2].center_m");
        assert_eq!(problem.location.origin, "rows/test.toml");
        assert_eq!(problem.location.line, Some(13));
        assert!(
            problem.reason.contains("overlaps section 1"),
            "{}",
            problem.reason
        );
        let message = RowError::Invalid(Box::new(problem)).to_string();
        assert!(message.starts_with("rows/test.toml:13"), "{message}");
    }

    #[test]
    fn inverted_platform_limits_are_refused() {
        let text = TWO_SECTIONS.replace("[0.0, 0.8]", "[0.8, 0.0]");
        let problem = invalid(&text);
        assert_eq!(problem.key, "platform.up_down_range_m");
        assert_eq!(problem.location.line, Some(5));
    }

    #[test]
    fn nan_is_refused_with_its_key() {
        let text = TWO_SECTIONS.replace("center_m = 2.0", "center_m = nan");
        let problem = invalid(&text);
        assert_eq!(problem.key, "section[2].center_m");
        assert_eq!(problem.location.line, Some(13));
        let text = TWO_SECTIONS.replace("[0.0, 0.5]", "[0.0, nan]");
        assert_eq!(invalid(&text).key, "platform.in_out_range_m");
    }

    #[test]
    fn placement_is_seeded_within_its_ranges_and_checked() {
        let text = TWO_SECTIONS.replacen(
            "[[section]]",
            "[placement]\ncanopy_setback_m = [0.15, 0.4]\nfruiting_zone_lift_m = [0.1, 0.5]\n\n[[section]]",
            1,
        );
        let row = RowScenario::from_toml_str("rows/test.toml", &text).expect("row");
        for index in 0..2 {
            let [setback, lift] = row.section_placement_m(index, 7);
            assert!((0.15..=0.4).contains(&setback), "{setback}");
            assert!((0.1..=0.5).contains(&lift), "{lift}");
            assert_eq!(row.section_placement_m(index, 7), [setback, lift]);
        }
        assert_ne!(row.section_placement_m(0, 7), row.section_placement_m(1, 7));
        let plain = RowScenario::from_toml_str("rows/test.toml", TWO_SECTIONS).expect("row");
        assert_eq!(plain.section_placement_m(1, 7), [0.0, 0.0]);

        let inverted = text.replace("[0.1, 0.5]", "[0.5, 0.1]");
        let problem = invalid(&inverted);
        assert_eq!(problem.key, "placement.fruiting_zone_lift_m");
        assert!(problem.location.line.is_some());
        let nan = text.replace("[0.15, 0.4]", "[nan, 0.4]");
        assert_eq!(invalid(&nan).key, "placement.canopy_setback_m");
        let too_far = text.replace("[0.15, 0.4]", "[0.15, 1.5]");
        let problem = invalid(&too_far);
        assert_eq!(problem.key, "placement.canopy_setback_m");
        assert_eq!(problem.location.line, Some(8));
    }

    #[test]
    fn unknown_canopy_and_unknown_keys_are_named() {
        let text = TWO_SECTIONS.replace("gala_vertical_wall", "pear");
        let problem = invalid(&text);
        assert_eq!(problem.key, "section[2].canopy");
        assert_eq!(problem.location.line, Some(12));
        let text = TWO_SECTIONS.replace("center_m = 2.0", "centre_m = 2.0");
        match RowScenario::from_toml_str("rows/test.toml", &text) {
            Err(RowError::Parse(ScenarioError::Parse { key, location, .. })) => {
                assert_eq!(key, "centre_m");
                assert!(location.line.is_some());
            }
            other => panic!("expected a parse error, got {other:?}"),
        }
    }
}
