//! Scenario files: everything that makes one simulated orchard different from another.
//!
//! A scenario is a TOML file (schema below, unknown keys rejected) describing the canopy, the
//! apples, the foliage, the light, the stems, the injected failure probabilities of the field
//! evaluation ([dual-arm Table 3]), the camera pose and, optionally, the camera and vacuum
//! hardware constants (defaults: [dual-arm sec. 2.1-2.3]). Named presets are compiled into the
//! binary from `processes/sim/scenarios/*.toml`.
//!
//! Frames: the robot frame has x forward (towards the canopy), y to the left, z up, metres; it is
//! the frame of the arm kinematics ([dual-arm eq. 1]). The camera frame is the ToF depth sensor's
//! optical frame (x right, y down, z forward); the RGB sensor sits `color_from_depth` away.

use std::path::{Path, PathBuf};

use harvest_ipc::camera_model::{CameraIntrinsics, RigidTransform};
use serde::{Deserialize, Serialize};
use toml::de::{DeTable, DeValue};

/// The presets compiled into the binary: `(name, TOML text)`.
const PRESETS: [(&str, &str); 4] = [
    ("default", include_str!("../scenarios/default.toml")),
    ("ideal", include_str!("../scenarios/ideal.toml")),
    (
        "gala_vertical_wall",
        include_str!("../scenarios/gala_vertical_wall.toml"),
    ),
    ("fuji_ufo", include_str!("../scenarios/fuji_ufo.toml")),
];

/// Names of the presets accepted by [`Scenario::preset`].
pub fn preset_names() -> impl Iterator<Item = &'static str> {
    PRESETS.iter().map(|(name, _)| *name)
}

/// Where in a scenario source a problem was found.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SourceLocation {
    /// File path, or `preset:<name>` for an embedded preset.
    pub origin: String,
    /// 1-based line, when the position is known.
    pub line: Option<usize>,
    /// 1-based column, when the position is known.
    pub column: Option<usize>,
}

impl std::fmt::Display for SourceLocation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}", self.origin)?;
        if let Some(line) = self.line {
            write!(f, ":{line}")?;
            if let Some(column) = self.column {
                write!(f, ":{column}")?;
            }
        }
        Ok(())
    }
}

/// Why a scenario could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum ScenarioError {
    /// The scenario file could not be read from disk.
    #[error("cannot read scenario file {path}: {source}")]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    /// The text is not valid TOML, or a key is unknown, missing or of the wrong type.
    #[error("{location}: key `{key}`: {message}")]
    Parse {
        location: SourceLocation,
        key: String,
        message: String,
    },
    /// A value parsed but lies outside its physical or logical range.
    #[error(transparent)]
    Invalid(Box<InvalidValue>),
    /// No preset has that name.
    #[error("unknown scenario preset `{name}` (known presets: {known})")]
    UnknownPreset { name: String, known: String },
}

/// A scenario value outside its allowed range.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{location}: key `{key}` = {value}: {reason}")]
pub struct InvalidValue {
    pub location: SourceLocation,
    /// Dotted key path, e.g. `failures.seal_failure`.
    pub key: String,
    pub value: String,
    pub reason: String,
}

/// One complete scenario.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    /// Short identifier (the preset name for presets).
    pub name: String,
    /// One sentence for humans.
    pub description: String,
    pub canopy: CanopyConfig,
    pub background: BackgroundConfig,
    pub apples: ApplesConfig,
    pub foliage: FoliageConfig,
    pub lighting: LightingConfig,
    pub stems: StemConfig,
    pub failures: FailureConfig,
    #[serde(default)]
    pub camera: CameraConfig,
    #[serde(default)]
    pub vacuum: VacuumConfig,
}

/// How the trees are trained; decides how branches are laid out.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CanopyStructure {
    /// Vertical fruiting wall: upright trunks at a fixed spacing with short lateral branches.
    FruitingWall,
    /// UFO (upright fruiting offshoots): a horizontal cordon low down with vertical uprights.
    Ufo,
}

/// The canopy wall in front of the robot.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CanopyConfig {
    pub structure: CanopyStructure,
    /// Robot-frame x of the canopy's front face (the side facing the robot), metres.
    pub front_x_m: f64,
    /// Depth (thickness) of the canopy wall along robot x, metres.
    pub depth_m: f64,
    /// Lateral extent of the foliage, robot y, metres `[min, max]`.
    pub y_range_m: [f64; 2],
    /// Vertical extent of the foliage, robot z, metres `[min, max]`.
    pub z_range_m: [f64; 2],
}

/// Everything behind and around the canopy.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BackgroundConfig {
    /// Robot-frame x of the next tree row, seen through gaps (a vertical plane), metres.
    pub next_row_x_m: f64,
    /// Top of the next row, robot z, metres; sky above (no depth return).
    pub next_row_top_z_m: f64,
    /// Ground plane height, robot z, metres.
    pub ground_z_m: f64,
    pub next_row_rgb: [u8; 3],
    pub ground_rgb: [u8; 3],
    pub sky_rgb: [u8; 3],
}

/// How apple centres are laid out.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AppleLayout {
    /// Uniformly random in the fruiting zone, at least `min_spacing_m` apart, with clusters.
    Random,
    /// A regular grid on one plane in the middle of the canopy depth (uniform distances to the
    /// arms, as assumed by the cycle-time analysis of [dual-arm Fig. 12]).
    Grid,
}

/// A normal distribution truncated to `[min, max]`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TruncatedNormal {
    pub mean: f64,
    pub std: f64,
    pub min: f64,
    pub max: f64,
}

/// The fruit.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ApplesConfig {
    /// Number of apples generated (cluster members included).
    pub count: u32,
    pub layout: AppleLayout,
    /// Minimum distance between the centres of apples that are not in the same cluster, metres.
    pub min_spacing_m: f64,
    /// Lateral extent of the fruiting zone, robot y, metres `[min, max]`.
    pub y_range_m: [f64; 2],
    /// Vertical extent of the fruiting zone, robot z, metres `[min, max]`.
    pub z_range_m: [f64; 2],
    /// Apple radius distribution, metres.
    pub radius_m: TruncatedNormal,
    /// Fraction of the apples that belong to a cluster of touching apples ([dual-arm Table 3],
    /// "Cluster").
    pub cluster_probability: f64,
    /// Apples per cluster, seed included, `[min, max]`.
    pub cluster_size: [u32; 2],
    /// Colour of the red blush of a bi-coloured apple.
    pub blush_rgb: [u8; 3],
    /// Colour of the unblushed ground colour.
    pub ground_rgb: [u8; 3],
    /// Fraction of the skin covered by blush, `[min, max]`, drawn per apple.
    pub blush_fraction: [f64; 2],
    /// Relative per-apple colour jitter (0 = identical apples).
    pub colour_jitter: f64,
}

/// Leaves (elliptical discs) and wood (cylinders).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FoliageConfig {
    /// Fraction of the canopy's frontal area covered by leaves as seen along robot x
    /// (Beer-Lambert coverage `1 - exp(-leaf area index)`), in `[0, 0.95]`.
    pub occlusion_fraction: f64,
    /// Leaf length (major axis), metres `[min, max]`.
    pub leaf_length_m: [f64; 2],
    /// Leaf width over length.
    pub leaf_width_ratio: f64,
    pub leaf_rgb: [u8; 3],
    /// Relative per-leaf colour jitter.
    pub colour_jitter: f64,
    /// Lateral branches (fruiting wall) or uprights (UFO).
    pub branch_count: u32,
    /// Branch radius, metres `[min, max]`.
    pub branch_radius_m: [f64; 2],
    /// Spacing of the trunks along robot y (fruiting wall only; 0 = no trunks), metres.
    pub trunk_spacing_m: f64,
    /// Trunk or cordon radius, metres.
    pub trunk_radius_m: f64,
    pub wood_rgb: [u8; 3],
}

/// Sun and sky light.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LightingConfig {
    /// Direction towards the sun in the robot frame (normalised on load).
    pub sun_direction_in_robot: [f64; 3],
    /// Direct sunlight, relative (1 = a clear day under the sun screen).
    pub sun_intensity: f64,
    /// Diffuse sky light, relative.
    pub ambient: f64,
    /// Strength of the specular highlight on apple skin, relative.
    pub specular: f64,
}

/// The stem's hold on the fruit.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StemConfig {
    /// Pull needed to detach a ripe apple, newtons.
    pub strength_n: TruncatedNormal,
    /// Pull needed to detach an unripe apple (drawn with probability
    /// `failures.insufficient_detachment_force`), uniform in `[min, max]` newtons; must exceed the
    /// end-effector's suction force so the vacuum cannot detach it.
    pub unripe_strength_n: [f64; 2],
    /// Stem stiffness once its slack is taken up, newtons per metre of pull.
    pub stiffness_n_per_m: f64,
    /// Free travel of the fruit before the stem pulls back, metres.
    pub slack_m: f64,
    /// Largest fraction of the stem strength that twisting the fruit relieves.
    pub twist_relief: f64,
    /// Twist at which the full relief is reached, radians.
    pub twist_full_rad: f64,
}

/// Failure probabilities, per harvest attempt or per apple ([dual-arm Table 3]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FailureConfig {
    /// Per attempt: a leaf or thin branch lies between cup and fruit, so no seal forms.
    pub seal_failure: f64,
    /// Per apple: the stem is unripe-strong, beyond the suction force.
    pub insufficient_detachment_force: f64,
    /// Per detached apple: a branch knocks it off the end-effector during the retract.
    pub holding_interference: f64,
    /// Per apple: sunlight saturates the apple's own visible surface (a specular highlight;
    /// occluders in front keep their colour).
    pub camera_overexposure: f64,
    /// Per apple: extra leaves right in front of it hide most of it.
    pub heavy_occlusion: f64,
}

/// Camera mounting and the ToF camera's error model (defaults: Percipio TL460-S1-E1,
/// [dual-arm sec. 2.1]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CameraConfig {
    /// Optical centre of the depth sensor in the robot frame, metres.
    pub position_in_robot_m: [f64; 3],
    /// A point the optical axis passes through, robot frame, metres.
    pub look_at_in_robot_m: [f64; 3],
    /// Translation of `color_from_depth` (RGB optical frame from depth optical frame; the two
    /// sensors are parallel), metres.
    pub color_from_depth_translation_m: [f64; 3],
    /// Constant part of the depth error, millimetres, taken as one standard deviation.
    pub depth_noise_mm: f64,
    /// Depth-proportional part of the depth error (0.0025 = 0.25 %), one standard deviation.
    pub depth_noise_fraction: f64,
    /// Working range; outside it the pixel reads 0 (no return), metres `[min, max]`.
    pub range_m: [f64; 2],
    /// Over-exposed patches: depth noise multiplier at the patch centre.
    pub overexposed_depth_noise_gain: f64,
    /// Over-exposed patches: probability a depth pixel at the patch centre has no return.
    pub overexposed_dropout_probability: f64,
    /// Over-exposed patch radius over the apple's radius.
    pub overexposed_patch_scale: f64,
}

impl Default for CameraConfig {
    fn default() -> Self {
        Self {
            position_in_robot_m: [0.0, 0.0, 0.9],
            look_at_in_robot_m: [1.35, 0.0, 0.3],
            color_from_depth_translation_m: [-0.025, 0.0, 0.0],
            depth_noise_mm: 4.0,
            depth_noise_fraction: 0.0025,
            range_m: [0.3, 9.5],
            overexposed_depth_noise_gain: 4.0,
            overexposed_dropout_probability: 0.5,
            overexposed_patch_scale: 1.6,
        }
    }
}

/// Why a camera pose cannot be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CameraPoseError {
    /// The look-at point coincides with the camera position.
    #[error("camera look-at point {look_at:?} coincides with its position")]
    DegenerateLookAt { look_at: [f64; 3] },
    /// The optical axis is vertical, so "right" is undefined.
    #[error("camera optical axis {axis:?} is vertical; tilt it towards the canopy")]
    VerticalAxis { axis: [f64; 3] },
}

impl CameraConfig {
    /// `robot_from_camera` (camera = depth optical frame) from the position and look-at point,
    /// with image "up" towards robot +z.
    pub fn robot_from_camera(&self) -> Result<RigidTransform, CameraPoseError> {
        let forward = sub(self.look_at_in_robot_m, self.position_in_robot_m);
        let forward = normalized(forward).ok_or(CameraPoseError::DegenerateLookAt {
            look_at: self.look_at_in_robot_m,
        })?;
        let right = normalized(cross(forward, [0.0, 0.0, 1.0]))
            .ok_or(CameraPoseError::VerticalAxis { axis: forward })?;
        let down = cross(forward, right);
        // Columns are the camera axes expressed in the robot frame.
        let rotation = [
            [right[0], down[0], forward[0]],
            [right[1], down[1], forward[1]],
            [right[2], down[2], forward[2]],
        ];
        Ok(RigidTransform {
            rotation,
            translation_m: self.position_in_robot_m,
        })
    }

    /// `color_from_depth`: a pure translation (parallel sensors).
    pub fn color_from_depth(&self) -> RigidTransform {
        RigidTransform::from_translation(self.color_from_depth_translation_m)
    }

    /// Intrinsics of the depth image (640x480).
    pub fn depth_intrinsics(&self) -> CameraIntrinsics {
        CameraIntrinsics::tl460_depth()
    }

    /// Intrinsics of the RGB image (1920x1080).
    pub fn color_intrinsics(&self) -> CameraIntrinsics {
        CameraIntrinsics::tl460_rgb()
    }

    /// One-sigma depth noise at a depth, millimetres: `depth_noise_mm + fraction * depth`.
    pub fn depth_sigma_mm(&self, depth_mm: f64) -> f64 {
        self.depth_noise_mm + self.depth_noise_fraction * depth_mm
    }
}

/// The centralized vacuum, the valve box and the end-effector ([dual-arm sec. 2.2-2.3]).
///
/// Conductances are linearised flow paths, m^3/h of air per mmH2O of pressure difference.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct VacuumConfig {
    /// Vacuum of the source with no flow (Delfin 202 DS: 2500 mmH2O).
    pub source_max_vacuum_mmh2o: f64,
    /// Flow of the source at zero vacuum (Delfin 202 DS: 360 m^3/h).
    pub source_max_flow_m3_per_h: f64,
    /// Time a butterfly valve takes from closed to open or back (paper: under 1 s).
    pub valve_travel_time_s: f64,
    /// Time constant of an arm line's pressure (tube volume over flow).
    pub line_time_constant_s: f64,
    /// Time constant of the source's pressure.
    pub source_time_constant_s: f64,
    /// Arm line to source through a fully open inlet valve (valve 1 or 3).
    pub inlet_conductance: f64,
    /// Arm line to atmosphere through a fully open vent valve (valve 2 or 4).
    pub vent_conductance: f64,
    /// End-effector open to air (no fruit).
    pub open_cup_conductance: f64,
    /// End-effector sealed on a fruit.
    pub sealed_cup_conductance: f64,
    /// End-effector on a fruit with a leaf in between (no seal).
    pub leaf_blocked_cup_conductance: f64,
    /// Source's own leakage.
    pub source_leak_conductance: f64,
    /// Holding force of a sealed cup at `source_max_vacuum_mmh2o`, newtons (paper: 47 N).
    pub suction_force_at_max_vacuum_n: f64,
    /// Largest gap between cup and apple surface that still seals (paper: 1.5 cm tolerance).
    pub seal_distance_m: f64,
    /// Holding force needed to draw the fruit into the cup, newtons.
    pub attach_min_force_n: f64,
    /// Below this holding force a detached fruit falls off the cup, newtons.
    pub hold_min_force_n: f64,
    /// A fruit released with its centre at robot x below this lands on the dropping module
    /// (harvested); elsewhere it falls to the ground, metres.
    pub dropping_module_max_x_m: f64,
    /// Travel from the detach point after which an injected holding interference knocks the
    /// fruit off, metres `[min, max]`.
    pub interference_travel_m: [f64; 2],
}

impl Default for VacuumConfig {
    fn default() -> Self {
        Self {
            source_max_vacuum_mmh2o: 2500.0,
            source_max_flow_m3_per_h: 360.0,
            valve_travel_time_s: 0.6,
            line_time_constant_s: 0.12,
            source_time_constant_s: 0.25,
            inlet_conductance: 0.5,
            vent_conductance: 1.0,
            open_cup_conductance: 0.3,
            sealed_cup_conductance: 0.005,
            leaf_blocked_cup_conductance: 0.2,
            source_leak_conductance: 0.002,
            suction_force_at_max_vacuum_n: 47.0,
            seal_distance_m: 0.015,
            attach_min_force_n: 8.0,
            hold_min_force_n: 3.0,
            // The module touches the canopy front ([dual-arm sec. 4.1]: the platform is
            // moved until the dropping module contacts the canopy; 1.15 m in every preset).
            // 1.1 m put arm 2's released apples (home cup at x = 1.07 m, Table 1) off it.
            dropping_module_max_x_m: 1.15,
            interference_travel_m: [0.05, 0.25],
        }
    }
}

impl Scenario {
    /// Loads an embedded preset by name (see [`preset_names`]).
    pub fn preset(name: &str) -> Result<Self, ScenarioError> {
        let Some((_, text)) = PRESETS.iter().find(|(preset, _)| *preset == name) else {
            return Err(ScenarioError::UnknownPreset {
                name: name.to_owned(),
                known: preset_names().collect::<Vec<_>>().join(", "),
            });
        };
        Self::from_toml_str(&format!("preset:{name}"), text)
    }

    /// Loads and validates a scenario file.
    pub fn from_file(path: &Path) -> Result<Self, ScenarioError> {
        let text = std::fs::read_to_string(path).map_err(|source| ScenarioError::Read {
            path: path.to_owned(),
            source,
        })?;
        Self::from_toml_str(&path.display().to_string(), &text)
    }

    /// Parses and validates scenario text; `origin` names the source in errors.
    pub fn from_toml_str(origin: &str, text: &str) -> Result<Self, ScenarioError> {
        let mut scenario: Scenario =
            toml::from_str(text).map_err(|error| parse_error(origin, text, &error))?;
        if let Err(problem) = scenario.validate() {
            let (line, column) = locate_key(text, &problem.key)
                .map_or((None, None), |(line, column)| (Some(line), Some(column)));
            return Err(ScenarioError::Invalid(Box::new(InvalidValue {
                location: SourceLocation {
                    origin: origin.to_owned(),
                    line,
                    column,
                },
                key: problem.key.join("."),
                value: problem.value,
                reason: problem.reason,
            })));
        }
        if let Some(sun) = normalized(scenario.lighting.sun_direction_in_robot) {
            scenario.lighting.sun_direction_in_robot = sun;
        }
        Ok(scenario)
    }

    /// Checks every range; the first problem found is returned.
    fn validate(&self) -> Result<(), Problem> {
        let mut check = Checker::default();
        let c = &self.canopy;
        check.range(&["canopy", "y_range_m"], c.y_range_m);
        check.range(&["canopy", "z_range_m"], c.z_range_m);
        check.positive(&["canopy", "depth_m"], c.depth_m);
        check.positive(&["canopy", "front_x_m"], c.front_x_m);
        let b = &self.background;
        if b.next_row_x_m <= c.front_x_m + c.depth_m {
            check.fail(
                &["background", "next_row_x_m"],
                b.next_row_x_m,
                "must lie behind the canopy (> canopy.front_x_m + canopy.depth_m)",
            );
        }
        if b.ground_z_m >= c.z_range_m[0] {
            check.fail(
                &["background", "ground_z_m"],
                b.ground_z_m,
                "must lie below the canopy (< canopy.z_range_m[0])",
            );
        }
        let a = &self.apples;
        check.range(&["apples", "y_range_m"], a.y_range_m);
        check.range(&["apples", "z_range_m"], a.z_range_m);
        check.non_negative(&["apples", "min_spacing_m"], a.min_spacing_m);
        check.distribution(&["apples", "radius_m"], a.radius_m);
        if a.radius_m.min <= 0.0 {
            check.fail(
                &["apples", "radius_m", "min"],
                a.radius_m.min,
                "must be > 0",
            );
        }
        if 2.0 * a.radius_m.max >= c.depth_m {
            check.fail(
                &["apples", "radius_m", "max"],
                a.radius_m.max,
                "an apple must fit in the canopy depth",
            );
        }
        check.probability(&["apples", "cluster_probability"], a.cluster_probability);
        if a.cluster_size[0] < 2 || a.cluster_size[0] > a.cluster_size[1] {
            check.fail_text(
                &["apples", "cluster_size"],
                format!("{:?}", a.cluster_size),
                "must be [min, max] with 2 <= min <= max",
            );
        }
        check.probability_range(&["apples", "blush_fraction"], a.blush_fraction);
        check.non_negative(&["apples", "colour_jitter"], a.colour_jitter);
        let f = &self.foliage;
        if !(0.0..=0.95).contains(&f.occlusion_fraction) {
            check.fail(
                &["foliage", "occlusion_fraction"],
                f.occlusion_fraction,
                "must be in [0, 0.95]",
            );
        }
        check.positive_range(&["foliage", "leaf_length_m"], f.leaf_length_m);
        check.positive(&["foliage", "leaf_width_ratio"], f.leaf_width_ratio);
        check.non_negative(&["foliage", "colour_jitter"], f.colour_jitter);
        check.positive_range(&["foliage", "branch_radius_m"], f.branch_radius_m);
        check.non_negative(&["foliage", "trunk_spacing_m"], f.trunk_spacing_m);
        check.positive(&["foliage", "trunk_radius_m"], f.trunk_radius_m);
        let l = &self.lighting;
        if normalized(l.sun_direction_in_robot).is_none() {
            check.fail_text(
                &["lighting", "sun_direction_in_robot"],
                format!("{:?}", l.sun_direction_in_robot),
                "must be a non-zero vector",
            );
        }
        check.non_negative(&["lighting", "sun_intensity"], l.sun_intensity);
        check.non_negative(&["lighting", "ambient"], l.ambient);
        check.non_negative(&["lighting", "specular"], l.specular);
        let s = &self.stems;
        check.distribution(&["stems", "strength_n"], s.strength_n);
        check.positive_range(&["stems", "unripe_strength_n"], s.unripe_strength_n);
        if s.unripe_strength_n[0] <= self.vacuum.suction_force_at_max_vacuum_n {
            check.fail_text(
                &["stems", "unripe_strength_n"],
                format!("{:?}", s.unripe_strength_n),
                "must exceed vacuum.suction_force_at_max_vacuum_n",
            );
        }
        check.positive(&["stems", "stiffness_n_per_m"], s.stiffness_n_per_m);
        check.non_negative(&["stems", "slack_m"], s.slack_m);
        check.probability(&["stems", "twist_relief"], s.twist_relief);
        check.positive(&["stems", "twist_full_rad"], s.twist_full_rad);
        let fl = &self.failures;
        check.probability(&["failures", "seal_failure"], fl.seal_failure);
        check.probability(
            &["failures", "insufficient_detachment_force"],
            fl.insufficient_detachment_force,
        );
        check.probability(
            &["failures", "holding_interference"],
            fl.holding_interference,
        );
        check.probability(&["failures", "camera_overexposure"], fl.camera_overexposure);
        check.probability(&["failures", "heavy_occlusion"], fl.heavy_occlusion);
        let cam = &self.camera;
        if let Err(error) = cam.robot_from_camera() {
            check.fail_text(
                &["camera", "look_at_in_robot_m"],
                format!("{:?}", cam.look_at_in_robot_m),
                &error.to_string(),
            );
        }
        check.non_negative(&["camera", "depth_noise_mm"], cam.depth_noise_mm);
        check.non_negative(
            &["camera", "depth_noise_fraction"],
            cam.depth_noise_fraction,
        );
        check.positive_range(&["camera", "range_m"], cam.range_m);
        if cam.overexposed_depth_noise_gain < 1.0 {
            check.fail(
                &["camera", "overexposed_depth_noise_gain"],
                cam.overexposed_depth_noise_gain,
                "must be >= 1",
            );
        }
        check.probability(
            &["camera", "overexposed_dropout_probability"],
            cam.overexposed_dropout_probability,
        );
        check.positive(
            &["camera", "overexposed_patch_scale"],
            cam.overexposed_patch_scale,
        );
        let v = &self.vacuum;
        for (key, value) in [
            ("source_max_vacuum_mmh2o", v.source_max_vacuum_mmh2o),
            ("source_max_flow_m3_per_h", v.source_max_flow_m3_per_h),
            ("valve_travel_time_s", v.valve_travel_time_s),
            ("line_time_constant_s", v.line_time_constant_s),
            ("source_time_constant_s", v.source_time_constant_s),
            ("inlet_conductance", v.inlet_conductance),
            ("vent_conductance", v.vent_conductance),
            ("open_cup_conductance", v.open_cup_conductance),
            (
                "suction_force_at_max_vacuum_n",
                v.suction_force_at_max_vacuum_n,
            ),
            ("seal_distance_m", v.seal_distance_m),
        ] {
            check.positive(&["vacuum", key], value);
        }
        for (key, value) in [
            ("sealed_cup_conductance", v.sealed_cup_conductance),
            (
                "leaf_blocked_cup_conductance",
                v.leaf_blocked_cup_conductance,
            ),
            ("source_leak_conductance", v.source_leak_conductance),
            ("attach_min_force_n", v.attach_min_force_n),
            ("hold_min_force_n", v.hold_min_force_n),
        ] {
            check.non_negative(&["vacuum", key], value);
        }
        check.positive_range(
            &["vacuum", "interference_travel_m"],
            v.interference_travel_m,
        );
        check.finish()
    }
}

/// One validation problem: key path, offending value, reason.
#[derive(Debug)]
struct Problem {
    key: Vec<&'static str>,
    value: String,
    reason: String,
}

/// Collects the first validation problem.
#[derive(Default)]
struct Checker {
    first: Option<Problem>,
}

impl Checker {
    fn fail_text(&mut self, key: &[&'static str], value: String, reason: &str) {
        if self.first.is_none() {
            self.first = Some(Problem {
                key: key.to_vec(),
                value,
                reason: reason.to_owned(),
            });
        }
    }

    fn fail(&mut self, key: &[&'static str], value: f64, reason: &str) {
        self.fail_text(key, value.to_string(), reason);
    }

    fn positive(&mut self, key: &[&'static str], value: f64) {
        if !(value > 0.0 && value.is_finite()) {
            self.fail(key, value, "must be > 0");
        }
    }

    fn non_negative(&mut self, key: &[&'static str], value: f64) {
        if !(value >= 0.0 && value.is_finite()) {
            self.fail(key, value, "must be >= 0");
        }
    }

    fn probability(&mut self, key: &[&'static str], value: f64) {
        if !(0.0..=1.0).contains(&value) {
            self.fail(key, value, "must be a probability in [0, 1]");
        }
    }

    fn range(&mut self, key: &[&'static str], range: [f64; 2]) {
        if !(range[0] < range[1] && range[0].is_finite() && range[1].is_finite()) {
            self.fail_text(
                key,
                format!("{range:?}"),
                "must be [min, max] with min < max",
            );
        }
    }

    fn positive_range(&mut self, key: &[&'static str], range: [f64; 2]) {
        if !(range[0] > 0.0 && range[0] <= range[1] && range[1].is_finite()) {
            self.fail_text(
                key,
                format!("{range:?}"),
                "must be [min, max] with 0 < min <= max",
            );
        }
    }

    fn probability_range(&mut self, key: &[&'static str], range: [f64; 2]) {
        if !(0.0 <= range[0] && range[0] <= range[1] && range[1] <= 1.0) {
            self.fail_text(
                key,
                format!("{range:?}"),
                "must be [min, max] within [0, 1]",
            );
        }
    }

    fn distribution(&mut self, key: &[&'static str], d: TruncatedNormal) {
        if !(d.std >= 0.0 && d.min <= d.mean && d.mean <= d.max && d.max.is_finite()) {
            self.fail_text(
                key,
                format!(
                    "{{ mean = {}, std = {}, min = {}, max = {} }}",
                    d.mean, d.std, d.min, d.max
                ),
                "must have std >= 0 and min <= mean <= max",
            );
        }
    }

    fn finish(self) -> Result<(), Problem> {
        self.first.map_or(Ok(()), Err)
    }
}

/// Turns a toml deserialisation error into one naming origin, line, column and key.
pub(crate) fn parse_error(origin: &str, text: &str, error: &toml::de::Error) -> ScenarioError {
    let message = error.message().trim().to_owned();
    let (line, column) = error.span().map_or((None, None), |span| {
        let (line, column) = line_column(text, span.start);
        (Some(line), Some(column))
    });
    let key = quoted_field(&message)
        .or_else(|| error.span().and_then(|span| key_before(text, span.start)))
        .unwrap_or_else(|| "<document>".to_owned());
    ScenarioError::Parse {
        location: SourceLocation {
            origin: origin.to_owned(),
            line,
            column,
        },
        key,
        message,
    }
}

/// The field named in serde messages such as "unknown field `x`" or "missing field `x`".
fn quoted_field(message: &str) -> Option<String> {
    let rest = message
        .strip_prefix("unknown field `")
        .or_else(|| message.strip_prefix("missing field `"))?;
    rest.split('`').next().map(str::to_owned)
}

/// The key whose value starts at or before `offset` (the identifier left of the nearest `=`).
fn key_before(text: &str, offset: usize) -> Option<String> {
    let head = text.get(..offset.min(text.len()))?;
    let equals = head.rfind('=')?;
    let key: String = head[..equals]
        .trim_end()
        .chars()
        .rev()
        .take_while(|c| c.is_ascii_alphanumeric() || *c == '_' || *c == '-')
        .collect();
    (!key.is_empty()).then(|| key.chars().rev().collect())
}

/// 1-based line and column of a byte offset.
pub(crate) fn line_column(text: &str, offset: usize) -> (usize, usize) {
    let head = text.get(..offset.min(text.len())).unwrap_or(text);
    let line = head.matches('\n').count() + 1;
    let column = head.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, column)
}

/// Line and column of the deepest key of `path` present in the document.
fn locate_key(text: &str, path: &[&str]) -> Option<(usize, usize)> {
    let document = DeTable::parse(text).ok()?;
    let mut table: &DeTable<'_> = document.get_ref();
    let mut found = None;
    for key in path {
        let (name, value) = table.iter().find(|(name, _)| name.get_ref() == key)?;
        found = Some(line_column(text, name.span().start));
        match value.get_ref() {
            DeValue::Table(inner) => table = inner,
            _ => break,
        }
    }
    found
}

pub(crate) fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

pub(crate) fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

pub(crate) fn norm(a: [f64; 3]) -> f64 {
    (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()
}

/// The unit vector along `a`, or `None` for a (near) zero or non-finite vector.
pub(crate) fn normalized(a: [f64; 3]) -> Option<[f64; 3]> {
    let length = norm(a);
    (length > 1e-12 && length.is_finite()).then(|| [a[0] / length, a[1] / length, a[2] / length])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_preset_loads_and_validates() {
        for name in preset_names() {
            let scenario = Scenario::preset(name).unwrap_or_else(|e| panic!("{name}: {e}"));
            assert_eq!(scenario.name, name);
        }
    }

    #[test]
    fn ideal_preset_has_no_failures_and_a_grid() {
        let ideal = Scenario::preset("ideal").expect("ideal");
        let f = &ideal.failures;
        assert_eq!(
            [
                f.seal_failure,
                f.insufficient_detachment_force,
                f.holding_interference,
                f.camera_overexposure,
                f.heavy_occlusion
            ],
            [0.0; 5]
        );
        assert_eq!(ideal.apples.layout, AppleLayout::Grid);
        assert_eq!(ideal.foliage.occlusion_fraction, 0.0);
        assert_eq!(ideal.apples.cluster_probability, 0.0);
    }

    #[test]
    fn unknown_preset_lists_the_known_ones() {
        let error = Scenario::preset("nope").expect_err("unknown");
        let text = error.to_string();
        assert!(text.contains("nope") && text.contains("ideal"), "{text}");
    }

    fn replace_line(text: &str, starts_with: &str, replacement: &str) -> (String, usize) {
        let mut line_number = 0;
        let lines: Vec<String> = text
            .lines()
            .enumerate()
            .map(|(i, line)| {
                if line.trim_start().starts_with(starts_with) && line_number == 0 {
                    line_number = i + 1;
                    replacement.to_owned()
                } else {
                    line.to_owned()
                }
            })
            .collect();
        assert!(line_number > 0, "no line starts with {starts_with}");
        (lines.join("\n"), line_number)
    }

    const DEFAULT_TEXT: &str = include_str!("../scenarios/default.toml");

    #[test]
    fn unknown_key_error_names_key_and_line() {
        let (text, line) = replace_line(DEFAULT_TEXT, "seal_failure", "seal_failur = 0.1");
        let error = Scenario::from_toml_str("bad.toml", &text).expect_err("unknown key");
        match &error {
            ScenarioError::Parse { location, key, .. } => {
                assert_eq!(key, "seal_failur");
                assert_eq!(location.line, Some(line));
                assert_eq!(location.origin, "bad.toml");
            }
            other => panic!("unexpected {other:?}"),
        }
        assert!(error.to_string().contains(&format!("bad.toml:{line}")));
    }

    #[test]
    fn wrong_type_error_names_key_and_line() {
        let (text, line) = replace_line(DEFAULT_TEXT, "count", "count = \"forty\"");
        let error = Scenario::from_toml_str("bad.toml", &text).expect_err("wrong type");
        match error {
            ScenarioError::Parse { location, key, .. } => {
                assert_eq!(key, "count");
                assert_eq!(location.line, Some(line));
            }
            other => panic!("unexpected {other:?}"),
        }
    }

    #[test]
    fn out_of_range_value_names_key_value_and_line() {
        let (text, line) = replace_line(
            DEFAULT_TEXT,
            "holding_interference",
            "holding_interference = 1.5",
        );
        let error = Scenario::from_toml_str("bad.toml", &text).expect_err("invalid");
        match error {
            ScenarioError::Invalid(invalid) => {
                assert_eq!(invalid.key, "failures.holding_interference");
                assert_eq!(invalid.value, "1.5");
                assert_eq!(invalid.location.line, Some(line));
            }
            other => panic!("unexpected {other:?}"),
        }
    }

    #[test]
    fn missing_file_names_the_path() {
        let error = Scenario::from_file(Path::new("/nonexistent/scenario.toml")).expect_err("io");
        assert!(error.to_string().contains("/nonexistent/scenario.toml"));
    }

    #[test]
    fn from_file_reads_a_written_scenario() {
        let path = std::env::temp_dir().join(format!("harvest-sim-{}.toml", std::process::id()));
        std::fs::write(&path, DEFAULT_TEXT).expect("write");
        let loaded = Scenario::from_file(&path).expect("load");
        std::fs::remove_file(&path).ok();
        assert_eq!(loaded, Scenario::preset("default").expect("default"));
    }

    #[test]
    fn look_at_pose_points_the_optical_axis_at_the_target() {
        let camera = CameraConfig::default();
        let robot_from_camera = camera.robot_from_camera().expect("pose");
        // The optical axis (camera +z) passes through the look-at point.
        let distance = norm(sub(camera.look_at_in_robot_m, camera.position_in_robot_m));
        let on_axis = robot_from_camera.apply([0.0, 0.0, distance]);
        for (got, want) in on_axis.iter().zip(camera.look_at_in_robot_m) {
            assert!((got - want).abs() < 1e-12);
        }
        // Image right is robot -y (the robot looks along +x), image down has negative z.
        let right = robot_from_camera.rotate([1.0, 0.0, 0.0]);
        assert!((right[1] + 1.0).abs() < 1e-12);
        let down = robot_from_camera.rotate([0.0, 1.0, 0.0]);
        assert!(down[2] < -0.8);
    }
}
