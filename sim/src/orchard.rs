//! Seeded generation of the simulated orchard: apples on a canopy wall, the leaves and wood that
//! hide them, and the world state that physics and rendering share.
//!
//! Everything is drawn from one `SmallRng` seeded by the caller, so a scenario and a seed give the
//! same world on every run of the same build.

use harvest_ipc::camera_model::RigidTransform;
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};

use crate::physics::{ArmId, PhysicsState};
use crate::scenario::{
    AppleLayout, CameraPoseError, CanopyStructure, Scenario, TruncatedNormal, cross, norm,
    normalized, sub,
};

/// Stable identifier of one apple in a world (its index in [`World::apples`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct AppleId(pub u32);

/// Where an apple is in the harvest (ground truth).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AppleState {
    /// Hanging on its stem.
    OnTree,
    /// Held by an arm's end-effector; `detached` once the stem let go.
    Attached { arm: ArmId, detached: bool },
    /// Fell to the ground (knocked off, released away from the dropping module).
    Dropped,
    /// Released onto the dropping module.
    Harvested,
}

/// One apple. Colours are linear RGB in `[0, 1]`.
#[derive(Debug, Clone, PartialEq)]
pub struct Apple {
    pub id: AppleId,
    /// Centre while hanging on the tree, robot frame, metres.
    pub rest_center_in_robot_m: [f64; 3],
    /// Current centre, robot frame, metres (moves with the end-effector when attached).
    pub center_in_robot_m: [f64; 3],
    pub radius_m: f64,
    pub blush_rgb: [f32; 3],
    pub ground_rgb: [f32; 3],
    /// Axis of the blushed cap (unit vector, robot frame).
    pub blush_axis_in_robot: [f64; 3],
    /// Fraction of the skin that is blushed.
    pub blush_fraction: f64,
    /// Pull on the stem that detaches the apple, newtons.
    pub stem_strength_n: f64,
    /// Cluster of touching apples this one belongs to.
    pub cluster: Option<u32>,
    /// Extra leaves were placed right in front of it (Table 3, "Occlusion").
    pub heavily_occluded: bool,
    /// Sunlight saturates the image around it (Table 3, "Exposure").
    pub overexposed: bool,
    pub state: AppleState,
}

/// A leaf: a flat ellipse.
#[derive(Debug, Clone, PartialEq)]
pub struct Leaf {
    pub center_in_robot_m: [f64; 3],
    /// Unit normal of the leaf blade.
    pub normal_in_robot: [f64; 3],
    /// Unit vector along the leaf's length, perpendicular to the normal.
    pub major_axis_in_robot: [f64; 3],
    pub half_length_m: f64,
    pub half_width_m: f64,
    pub rgb: [f32; 3],
}

/// A branch, trunk, upright or cordon: a cylinder.
#[derive(Debug, Clone, PartialEq)]
pub struct Branch {
    pub start_in_robot_m: [f64; 3],
    pub end_in_robot_m: [f64; 3],
    pub radius_m: f64,
    pub rgb: [f32; 3],
}

/// Why a world could not be generated.
#[derive(Debug, thiserror::Error)]
pub enum OrchardError {
    /// Random placement gave up: the fruiting zone is too small for the count and spacing.
    #[error(
        "placed only {placed} of apples.count = {requested} apples at apples.min_spacing_m = \
         {min_spacing_m} m: enlarge the fruiting zone or lower the count"
    )]
    ApplePlacement {
        requested: u32,
        placed: u32,
        min_spacing_m: f64,
    },
    /// The grid layout would put apples closer than the minimum spacing.
    #[error(
        "a grid of {count} apples in the fruiting zone has a spacing of {spacing_m:.3} m, below \
         apples.min_spacing_m = {min_spacing_m} m"
    )]
    GridTooDense {
        count: u32,
        spacing_m: f64,
        min_spacing_m: f64,
    },
    /// A row without sections (a loaded [`crate::row::RowScenario`] always has one).
    #[error("a row needs at least one section")]
    EmptyRow,
    /// The camera pose of the scenario is degenerate.
    #[error("camera pose: {0}")]
    CameraPose(#[from] CameraPoseError),
}

/// The simulated world: orchard geometry, apple states and the vacuum/contact physics state.
#[derive(Debug, Clone)]
pub struct World {
    pub(crate) scenario: Scenario,
    pub(crate) seed: u64,
    pub(crate) robot_from_camera: RigidTransform,
    pub(crate) apples: Vec<Apple>,
    pub(crate) leaves: Vec<Leaf>,
    pub(crate) branches: Vec<Branch>,
    pub(crate) physics: PhysicsState,
    /// Where the robot stands in the row frame (trailer along y, platform stages along x and
    /// z), m; the geometry above is kept in the robot frame (see [`crate::world_motion`]).
    pub(crate) robot_offset_m: [f64; 3],
}

/// Mean projected area factor of a leaf tilted uniformly up to 60 degrees from facing the robot:
/// `E[cos tilt] = sin(60 deg) / (60 deg in rad)`.
const MEAN_LEAF_FACING: f64 = 0.827;
/// Largest tilt of a canopy leaf's normal away from the robot's -x axis, radians.
const MAX_LEAF_TILT_RAD: f64 = std::f64::consts::FRAC_PI_3;
/// Gap kept between apples that touch in a cluster, metres.
const CLUSTER_GAP_M: f64 = 0.0005;
/// Leaves placed in front of a heavily occluded apple.
const HEAVY_OCCLUSION_LEAVES: usize = 3;

impl World {
    /// Generates the world of `scenario` from `seed`.
    pub fn generate(scenario: &Scenario, seed: u64) -> Result<Self, OrchardError> {
        let robot_from_camera = scenario.camera.robot_from_camera()?;
        let mut rng = SmallRng::seed_from_u64(seed);
        let mut apples = place_apples(scenario, &mut rng)?;
        decorate_apples(scenario, &mut apples, &mut rng);
        let mut leaves = place_canopy_leaves(scenario, &apples, &mut rng);
        place_occluding_leaves(
            scenario,
            &apples,
            robot_from_camera.translation_m,
            &mut leaves,
            &mut rng,
        );
        let branches = place_branches(scenario, &mut rng);
        tracing::debug!(
            scenario = %scenario.name,
            seed,
            apples = apples.len(),
            leaves = leaves.len(),
            branches = branches.len(),
            "generated orchard world"
        );
        Ok(Self {
            physics: PhysicsState::new(&scenario.vacuum, seed),
            scenario: scenario.clone(),
            seed,
            robot_from_camera,
            apples,
            leaves,
            branches,
            robot_offset_m: [0.0; 3],
        })
    }

    pub fn scenario(&self) -> &Scenario {
        &self.scenario
    }

    pub fn seed(&self) -> u64 {
        self.seed
    }

    /// The depth camera's pose in the robot frame.
    pub fn robot_from_camera(&self) -> RigidTransform {
        self.robot_from_camera
    }

    pub fn apples(&self) -> &[Apple] {
        &self.apples
    }

    pub fn leaves(&self) -> &[Leaf] {
        &self.leaves
    }

    pub fn branches(&self) -> &[Branch] {
        &self.branches
    }
}

/// Samples a truncated normal by rejection (clamped after 32 misses).
pub(crate) fn sample_truncated(rng: &mut SmallRng, d: TruncatedNormal) -> f64 {
    let Ok(normal) = Normal::new(d.mean, d.std) else {
        return d.mean;
    };
    for _ in 0..32 {
        let value = normal.sample(rng);
        if (d.min..=d.max).contains(&value) {
            return value;
        }
    }
    d.mean.clamp(d.min, d.max)
}

fn uniform(rng: &mut SmallRng, range: [f64; 2]) -> f64 {
    if range[1] > range[0] {
        rng.random_range(range[0]..range[1])
    } else {
        range[0]
    }
}

/// A uniformly distributed unit vector.
fn random_unit(rng: &mut SmallRng) -> [f64; 3] {
    let z: f64 = rng.random_range(-1.0..1.0);
    let azimuth: f64 = rng.random_range(0.0..std::f64::consts::TAU);
    let radial = (1.0 - z * z).sqrt();
    [radial * azimuth.cos(), radial * azimuth.sin(), z]
}

/// A unit vector within `max_tilt_rad` of `axis` (uniform in tilt angle and azimuth).
fn tilted(rng: &mut SmallRng, axis: [f64; 3], max_tilt_rad: f64) -> [f64; 3] {
    let helper = if axis[2].abs() < 0.9 {
        [0.0, 0.0, 1.0]
    } else {
        [1.0, 0.0, 0.0]
    };
    let e1 = normalized(cross(axis, helper)).unwrap_or([0.0, 1.0, 0.0]);
    let e2 = cross(axis, e1);
    let tilt = rng.random_range(0.0..=max_tilt_rad);
    let azimuth: f64 = rng.random_range(0.0..std::f64::consts::TAU);
    let (s, c) = tilt.sin_cos();
    let (sa, ca) = azimuth.sin_cos();
    std::array::from_fn(|k| c * axis[k] + s * (ca * e1[k] + sa * e2[k]))
}

/// A unit vector perpendicular to `normal`, at a random angle.
fn random_perpendicular(rng: &mut SmallRng, normal: [f64; 3]) -> [f64; 3] {
    let helper = if normal[2].abs() < 0.9 {
        [0.0, 0.0, 1.0]
    } else {
        [1.0, 0.0, 0.0]
    };
    let e1 = normalized(cross(normal, helper)).unwrap_or([0.0, 1.0, 0.0]);
    let e2 = cross(normal, e1);
    let angle: f64 = rng.random_range(0.0..std::f64::consts::TAU);
    let (s, c) = angle.sin_cos();
    std::array::from_fn(|k| c * e1[k] + s * e2[k])
}

fn jittered_rgb(rng: &mut SmallRng, rgb: [u8; 3], jitter: f64) -> [f32; 3] {
    let brightness = 1.0 + uniform(rng, [-jitter, jitter]);
    std::array::from_fn(|k| {
        let channel = 1.0 + uniform(rng, [-jitter, jitter]) * 0.5;
        ((f64::from(rgb[k]) / 255.0) * brightness * channel).clamp(0.0, 1.0) as f32
    })
}

fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    norm(sub(a, b))
}

/// A bare apple at `center` (attributes filled in by [`decorate_apples`]).
fn bare_apple(index: usize, center: [f64; 3], radius_m: f64, cluster: Option<u32>) -> Apple {
    Apple {
        id: AppleId(index as u32),
        rest_center_in_robot_m: center,
        center_in_robot_m: center,
        radius_m,
        blush_rgb: [0.0; 3],
        ground_rgb: [0.0; 3],
        blush_axis_in_robot: [-1.0, 0.0, 0.0],
        blush_fraction: 0.0,
        stem_strength_n: 0.0,
        cluster,
        heavily_occluded: false,
        overexposed: false,
        state: AppleState::OnTree,
    }
}

fn place_apples(scenario: &Scenario, rng: &mut SmallRng) -> Result<Vec<Apple>, OrchardError> {
    match scenario.apples.layout {
        AppleLayout::Grid => place_apples_on_grid(scenario),
        AppleLayout::Random => place_apples_randomly(scenario, rng),
    }
}

/// A regular grid on the plane in the middle of the canopy depth.
fn place_apples_on_grid(scenario: &Scenario) -> Result<Vec<Apple>, OrchardError> {
    let a = &scenario.apples;
    let count = a.count as usize;
    if count == 0 {
        return Ok(Vec::new());
    }
    let width = a.y_range_m[1] - a.y_range_m[0];
    let height = a.z_range_m[1] - a.z_range_m[0];
    let columns = ((count as f64 * width / height).sqrt().ceil() as usize).clamp(1, count);
    let rows = count.div_ceil(columns);
    let step_y = if columns > 1 {
        width / (columns - 1) as f64
    } else {
        f64::INFINITY
    };
    let step_z = if rows > 1 {
        height / (rows - 1) as f64
    } else {
        f64::INFINITY
    };
    let spacing_m = step_y.min(step_z);
    if spacing_m < a.min_spacing_m || spacing_m < 2.0 * a.radius_m.max {
        return Err(OrchardError::GridTooDense {
            count: a.count,
            spacing_m,
            min_spacing_m: a.min_spacing_m,
        });
    }
    let x = scenario.canopy.front_x_m + scenario.canopy.depth_m / 2.0;
    let radius = a.radius_m.mean;
    Ok((0..count)
        .map(|index| {
            let (row, column) = (index / columns, index % columns);
            let y = if columns > 1 {
                a.y_range_m[1] - column as f64 * step_y
            } else {
                (a.y_range_m[0] + a.y_range_m[1]) / 2.0
            };
            let z = if rows > 1 {
                a.z_range_m[1] - row as f64 * step_z
            } else {
                (a.z_range_m[0] + a.z_range_m[1]) / 2.0
            };
            bare_apple(index, [x, y, z], radius, None)
        })
        .collect())
}

/// Random centres at least `min_spacing_m` apart; a fraction of them grow clusters of touching
/// apples. The seed probability `q` is chosen so that the expected fraction of apples in clusters
/// equals `cluster_probability = f`: with mean cluster size `k`, `f = q k / (1 - q + q k)`.
fn place_apples_randomly(
    scenario: &Scenario,
    rng: &mut SmallRng,
) -> Result<Vec<Apple>, OrchardError> {
    let a = &scenario.apples;
    let c = &scenario.canopy;
    let requested = a.count as usize;
    let mean_size = f64::from(a.cluster_size[0] + a.cluster_size[1]) / 2.0;
    let f = a.cluster_probability;
    let seed_probability = (f / (mean_size - f * (mean_size - 1.0))).clamp(0.0, 1.0);
    let mut apples: Vec<Apple> = Vec::with_capacity(requested);
    let mut clusters = 0u32;
    let mut misses = 0usize;
    let max_misses = 500 * requested.max(1);
    while apples.len() < requested {
        let radius = sample_truncated(rng, a.radius_m);
        let center = [
            uniform(
                rng,
                [c.front_x_m + radius, c.front_x_m + c.depth_m - radius],
            ),
            uniform(rng, a.y_range_m),
            uniform(rng, a.z_range_m),
        ];
        let clear = apples.iter().all(|other| {
            distance(other.rest_center_in_robot_m, center)
                >= a.min_spacing_m.max(other.radius_m + radius + CLUSTER_GAP_M)
        });
        if !clear {
            misses += 1;
            if misses > max_misses {
                return Err(OrchardError::ApplePlacement {
                    requested: a.count,
                    placed: apples.len() as u32,
                    min_spacing_m: a.min_spacing_m,
                });
            }
            continue;
        }
        let seed_index = apples.len();
        apples.push(bare_apple(seed_index, center, radius, None));
        if seed_probability > 0.0 && rng.random_bool(seed_probability) {
            let size = rng.random_range(a.cluster_size[0]..=a.cluster_size[1]) as usize;
            let members = grow_cluster(scenario, &mut apples, seed_index, size, clusters, rng);
            if members > 1 {
                apples[seed_index].cluster = Some(clusters);
                clusters += 1;
            }
        }
    }
    Ok(apples)
}

/// Adds up to `size - 1` apples touching members of the cluster seeded at `seed_index`; returns
/// the number of members including the seed.
fn grow_cluster(
    scenario: &Scenario,
    apples: &mut Vec<Apple>,
    seed_index: usize,
    size: usize,
    cluster: u32,
    rng: &mut SmallRng,
) -> usize {
    let a = &scenario.apples;
    let c = &scenario.canopy;
    let mut members = vec![seed_index];
    while members.len() < size && apples.len() < a.count as usize {
        let mut placed = false;
        for _ in 0..30 {
            let anchor = &apples[members[rng.random_range(0..members.len())]];
            let radius = sample_truncated(rng, a.radius_m);
            // Mostly beside or below each other in the wall plane.
            let raw = random_unit(rng);
            let Some(direction) = normalized([raw[0] * 0.3, raw[1], raw[2]]) else {
                continue;
            };
            let reach = anchor.radius_m + radius + CLUSTER_GAP_M;
            let center: [f64; 3] =
                std::array::from_fn(|k| anchor.rest_center_in_robot_m[k] + direction[k] * reach);
            let inside = center[0] - radius >= c.front_x_m
                && center[0] + radius <= c.front_x_m + c.depth_m
                && (c.y_range_m[0]..=c.y_range_m[1]).contains(&center[1])
                && (c.z_range_m[0]..=c.z_range_m[1]).contains(&center[2]);
            let clear = apples.iter().enumerate().all(|(index, other)| {
                let gap = distance(other.rest_center_in_robot_m, center);
                let needed = if members.contains(&index) {
                    other.radius_m + radius + CLUSTER_GAP_M * 0.5
                } else {
                    a.min_spacing_m.max(other.radius_m + radius + CLUSTER_GAP_M)
                };
                gap >= needed
            });
            if inside && clear {
                let index = apples.len();
                apples.push(bare_apple(index, center, radius, Some(cluster)));
                members.push(index);
                placed = true;
                break;
            }
        }
        if !placed {
            break;
        }
    }
    members.len()
}

/// Colours, stems, occlusion and exposure flags.
fn decorate_apples(scenario: &Scenario, apples: &mut [Apple], rng: &mut SmallRng) {
    let a = &scenario.apples;
    let failures = &scenario.failures;
    for apple in apples {
        apple.blush_rgb = jittered_rgb(rng, a.blush_rgb, a.colour_jitter);
        apple.ground_rgb = jittered_rgb(rng, a.ground_rgb, a.colour_jitter);
        let bias = random_unit(rng);
        apple.blush_axis_in_robot =
            normalized(std::array::from_fn(|k| [-1.0, 0.0, 0.4][k] + 0.7 * bias[k]))
                .unwrap_or([-1.0, 0.0, 0.0]);
        apple.blush_fraction = uniform(rng, a.blush_fraction);
        apple.stem_strength_n = if rng.random_bool(failures.insufficient_detachment_force) {
            uniform(rng, scenario.stems.unripe_strength_n)
        } else {
            sample_truncated(rng, scenario.stems.strength_n)
        };
        apple.heavily_occluded = rng.random_bool(failures.heavy_occlusion);
        apple.overexposed = rng.random_bool(failures.camera_overexposure);
    }
}

fn random_leaf(
    scenario: &Scenario,
    rng: &mut SmallRng,
    center: [f64; 3],
    facing: [f64; 3],
    max_tilt_rad: f64,
    length_scale: Option<f64>,
) -> Leaf {
    let f = &scenario.foliage;
    let normal = tilted(rng, facing, max_tilt_rad);
    let half_length_m = length_scale.unwrap_or_else(|| uniform(rng, f.leaf_length_m) / 2.0);
    Leaf {
        center_in_robot_m: center,
        normal_in_robot: normal,
        major_axis_in_robot: random_perpendicular(rng, normal),
        half_length_m,
        half_width_m: half_length_m * f.leaf_width_ratio,
        rgb: jittered_rgb(rng, f.leaf_rgb, f.colour_jitter),
    }
}

/// Leaves scattered through the canopy volume so that their frontal coverage is
/// `occlusion_fraction`: `N = -ln(1 - f) * A_canopy / (pi * a * b * E[cos tilt])`.
fn place_canopy_leaves(scenario: &Scenario, apples: &[Apple], rng: &mut SmallRng) -> Vec<Leaf> {
    let f = &scenario.foliage;
    let c = &scenario.canopy;
    if f.occlusion_fraction <= 0.0 {
        return Vec::new();
    }
    let canopy_area = (c.y_range_m[1] - c.y_range_m[0]) * (c.z_range_m[1] - c.z_range_m[0]);
    let mean_half_length = (f.leaf_length_m[0] + f.leaf_length_m[1]) / 4.0;
    let leaf_area = std::f64::consts::PI * mean_half_length * mean_half_length * f.leaf_width_ratio;
    let count = (-(1.0 - f.occlusion_fraction).ln() * canopy_area / (leaf_area * MEAN_LEAF_FACING))
        .ceil() as usize;
    let mut leaves = Vec::with_capacity(count + apples.len() * HEAVY_OCCLUSION_LEAVES);
    for _ in 0..count {
        for _ in 0..5 {
            let center = [
                uniform(rng, [c.front_x_m - 0.03, c.front_x_m + c.depth_m]),
                uniform(rng, c.y_range_m),
                uniform(rng, c.z_range_m),
            ];
            let inside_apple = apples.iter().any(|apple| {
                distance(apple.rest_center_in_robot_m, center) < apple.radius_m + 0.005
            });
            if !inside_apple {
                leaves.push(random_leaf(
                    scenario,
                    rng,
                    center,
                    [-1.0, 0.0, 0.0],
                    MAX_LEAF_TILT_RAD,
                    None,
                ));
                break;
            }
        }
    }
    leaves
}

/// Leaves right in front of heavily occluded apples, between the apple and the camera.
fn place_occluding_leaves(
    scenario: &Scenario,
    apples: &[Apple],
    camera_in_robot_m: [f64; 3],
    leaves: &mut Vec<Leaf>,
    rng: &mut SmallRng,
) {
    for apple in apples.iter().filter(|apple| apple.heavily_occluded) {
        let center = apple.rest_center_in_robot_m;
        let Some(towards_camera) = normalized(sub(camera_in_robot_m, center)) else {
            continue;
        };
        let e1 = random_perpendicular(rng, towards_camera);
        let e2 = cross(towards_camera, e1);
        for _ in 0..HEAVY_OCCLUSION_LEAVES {
            let ahead = apple.radius_m + uniform(rng, [0.01, 0.03]);
            let (s1, s2) = (
                uniform(rng, [-0.5, 0.5]) * apple.radius_m,
                uniform(rng, [-0.5, 0.5]) * apple.radius_m,
            );
            let leaf_center = std::array::from_fn(|k| {
                center[k] + towards_camera[k] * ahead + e1[k] * s1 + e2[k] * s2
            });
            let half_length = apple.radius_m * uniform(rng, [1.0, 1.4]);
            leaves.push(random_leaf(
                scenario,
                rng,
                leaf_center,
                towards_camera,
                0.35,
                Some(half_length),
            ));
        }
    }
}

fn wood(
    rng: &mut SmallRng,
    scenario: &Scenario,
    start: [f64; 3],
    end: [f64; 3],
    radius_m: f64,
) -> Branch {
    Branch {
        start_in_robot_m: start,
        end_in_robot_m: end,
        radius_m,
        rgb: jittered_rgb(
            rng,
            scenario.foliage.wood_rgb,
            scenario.foliage.colour_jitter * 0.5,
        ),
    }
}

/// Trunks and laterals (fruiting wall) or a cordon with uprights (UFO).
fn place_branches(scenario: &Scenario, rng: &mut SmallRng) -> Vec<Branch> {
    let f = &scenario.foliage;
    let c = &scenario.canopy;
    let ground_z = scenario.background.ground_z_m;
    let mid_x = c.front_x_m + c.depth_m * 0.6;
    let mut branches = Vec::new();
    match c.structure {
        CanopyStructure::FruitingWall => {
            let mut trunk_ys = Vec::new();
            if f.trunk_spacing_m > 0.0 {
                let mut y = c.y_range_m[0] + f.trunk_spacing_m * uniform(rng, [0.2, 0.8]);
                while y < c.y_range_m[1] {
                    trunk_ys.push(y);
                    let lean = uniform(rng, [-0.03, 0.03]);
                    branches.push(wood(
                        rng,
                        scenario,
                        [mid_x, y, ground_z],
                        [mid_x + lean, y, c.z_range_m[1]],
                        f.trunk_radius_m,
                    ));
                    y += f.trunk_spacing_m;
                }
            }
            for _ in 0..f.branch_count {
                let y0 = if trunk_ys.is_empty() {
                    uniform(rng, c.y_range_m)
                } else {
                    trunk_ys[rng.random_range(0..trunk_ys.len())]
                };
                let start = [mid_x, y0, uniform(rng, c.z_range_m)];
                let side = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
                let slope: f64 = uniform(rng, [-0.35, 0.35]);
                let length = uniform(rng, [0.25, 0.6]);
                let direction = normalized([uniform(rng, [-0.15, 0.15]), side, slope])
                    .unwrap_or([0.0, 1.0, 0.0]);
                let end = std::array::from_fn(|k| start[k] + direction[k] * length);
                let radius = uniform(rng, f.branch_radius_m);
                branches.push(wood(rng, scenario, start, end, radius));
            }
        }
        CanopyStructure::Ufo => {
            let cordon_z = c.z_range_m[0] - 0.05;
            branches.push(wood(
                rng,
                scenario,
                [mid_x, c.y_range_m[0], cordon_z],
                [mid_x, c.y_range_m[1], cordon_z],
                f.trunk_radius_m,
            ));
            let trunk_y = uniform(rng, c.y_range_m);
            branches.push(wood(
                rng,
                scenario,
                [mid_x, trunk_y, ground_z],
                [mid_x, trunk_y, cordon_z],
                f.trunk_radius_m,
            ));
            let count = f.branch_count.max(1) as f64;
            let step = (c.y_range_m[1] - c.y_range_m[0]) / count;
            for k in 0..f.branch_count {
                let y =
                    c.y_range_m[0] + step * (f64::from(k) + 0.5) + uniform(rng, [-0.2, 0.2]) * step;
                let x = c.front_x_m + c.depth_m * uniform(rng, [0.35, 0.65]);
                let height = c.z_range_m[1] - cordon_z;
                let top = [
                    x + uniform(rng, [-0.05, 0.05]) * height,
                    y + uniform(rng, [-0.12, 0.12]) * height,
                    c.z_range_m[1],
                ];
                let radius = uniform(rng, f.branch_radius_m);
                branches.push(wood(rng, scenario, [x, y, cordon_z], top, radius));
            }
        }
    }
    branches
}

#[cfg(test)]
mod tests {
    use super::*;

    fn world(preset: &str, seed: u64) -> World {
        let scenario = Scenario::preset(preset).expect("preset");
        World::generate(&scenario, seed).expect("world")
    }

    #[test]
    fn same_seed_same_world_different_seed_different_world() {
        let a = world("default", 7);
        let b = world("default", 7);
        let c = world("default", 8);
        assert_eq!(a.apples, b.apples);
        assert_eq!(a.leaves, b.leaves);
        assert_eq!(a.branches, b.branches);
        assert_ne!(a.apples, c.apples);
    }

    #[test]
    fn every_preset_generates_the_requested_apples_inside_the_canopy() {
        for name in crate::scenario::preset_names() {
            let w = world(name, 3);
            let s = w.scenario();
            assert_eq!(w.apples().len(), s.apples.count as usize, "{name}");
            for apple in w.apples() {
                let [x, _, _] = apple.center_in_robot_m;
                assert!(
                    x - apple.radius_m >= s.canopy.front_x_m - 1e-9,
                    "{name}: {apple:?}"
                );
                assert!(x + apple.radius_m <= s.canopy.front_x_m + s.canopy.depth_m + 1e-9);
                assert!(
                    apple.radius_m >= s.apples.radius_m.min
                        && apple.radius_m <= s.apples.radius_m.max
                );
            }
        }
    }

    #[test]
    fn apples_never_overlap_and_cluster_members_touch() {
        let w = world("fuji_ufo", 11);
        let apples = w.apples();
        let mut touching_pairs = 0;
        for (i, a) in apples.iter().enumerate() {
            for b in &apples[i + 1..] {
                let gap =
                    distance(a.center_in_robot_m, b.center_in_robot_m) - a.radius_m - b.radius_m;
                assert!(gap >= 0.0, "{a:?} overlaps {b:?}");
                if a.cluster.is_some() && a.cluster == b.cluster && gap < 0.002 {
                    touching_pairs += 1;
                }
                if a.cluster.is_none() || a.cluster != b.cluster {
                    assert!(
                        gap + a.radius_m + b.radius_m >= w.scenario().apples.min_spacing_m - 1e-9
                    );
                }
            }
        }
        let clustered = apples.iter().filter(|a| a.cluster.is_some()).count();
        assert!(clustered >= 2, "expected clusters, got {clustered}");
        assert!(
            touching_pairs >= clustered / 2,
            "{touching_pairs} touching pairs"
        );
    }

    #[test]
    fn cluster_fraction_matches_the_scenario_over_many_worlds() {
        let scenario = Scenario::preset("default").expect("default");
        let (mut clustered, mut total) = (0usize, 0usize);
        for seed in 0..40 {
            let w = World::generate(&scenario, seed).expect("world");
            clustered += w.apples().iter().filter(|a| a.cluster.is_some()).count();
            total += w.apples().len();
        }
        let fraction = clustered as f64 / total as f64;
        // Clusters that cannot grow (no room) lower the fraction a little.
        assert!(
            (fraction - scenario.apples.cluster_probability).abs() < 0.08,
            "clustered fraction {fraction}"
        );
    }

    #[test]
    fn ideal_grid_is_uniform_and_unoccluded() {
        let w = world("ideal", 1);
        assert!(w.leaves().is_empty());
        assert!(w.branches().is_empty());
        let xs: Vec<f64> = w.apples().iter().map(|a| a.center_in_robot_m[0]).collect();
        assert!(xs.iter().all(|x| (x - xs[0]).abs() < 1e-12));
        assert!(
            w.apples()
                .iter()
                .all(|a| !a.heavily_occluded && !a.overexposed && a.cluster.is_none())
        );
    }

    #[test]
    fn leaf_count_follows_the_occlusion_fraction() {
        let scenario = Scenario::preset("default").expect("default");
        let w = World::generate(&scenario, 5).expect("world");
        let heavy = w.apples().iter().filter(|a| a.heavily_occluded).count();
        let canopy_leaves = w.leaves().len() - heavy * HEAVY_OCCLUSION_LEAVES;
        // Frontal coverage 1 - exp(-sum of projected leaf areas / canopy area).
        let c = &scenario.canopy;
        let area = (c.y_range_m[1] - c.y_range_m[0]) * (c.z_range_m[1] - c.z_range_m[0]);
        let projected: f64 = w.leaves()[..canopy_leaves]
            .iter()
            .map(|l| {
                std::f64::consts::PI * l.half_length_m * l.half_width_m * l.normal_in_robot[0].abs()
            })
            .sum();
        let coverage = 1.0 - (-projected / area).exp();
        assert!(
            (coverage - scenario.foliage.occlusion_fraction).abs() < 0.03,
            "coverage {coverage}"
        );
    }
}
