//! The simulated solid-state LiDAR (Livox Mid-70, [fusion Table II]) looking at the
//! same orchard world as the ToF camera, serving `hw/lidar/points` (enabled by `harvest sim
//! --lidar`).
//!
//! Mounting: the LiDAR is rigidly attached to the ToF camera's colour sensor by
//! [`LidarDeviceConfig::camera_from_lidar`] (default: the CAD pose off by a plausible assembly
//! error, [`simulated_camera_from_lidar`]; what the calibration must recover). A scenario that
//! moves the camera moves the LiDAR with it.
//!
//! Each return: the next direction of the rosette scan ([`RosetteScan`]) with Gaussian direction
//! noise is cast against the world; the hit's range gets Gaussian range noise
//! ([`LidarSpec::range_sigma_m`]); returns outside the working range (and sky) are not reported.
//! Intensity follows the surface's albedo and incidence angle on the Livox 0-150 diffuse scale.
//!
//! What the LiDAR sees of the world (documented approximations): apples and leaves are taken
//! from the ALACS scene builder ([`fill_scene`]: apples as spheres, leaves as discs of the same
//! area) and intersected with [`AlacsScene::ray_cast`]; branches are not seen; the next tree row
//! and the ground are the renderer's planes (vertical plane at `next_row_x_m` up to
//! `next_row_top_z_m`, horizontal ground at `ground_z_m`). Beam divergence and mixed returns at
//! edges are not simulated.
//!
//! Cost: objects are sorted once per frame into a grid of buckets over the field of view (by
//! the tangent-plane bounds of their bounding spheres), so each ray is tested only against the
//! few objects of its bucket.

use crate::alacs::AlacsScene;
use crate::rosette_scan::RosetteScan;
use crate::rosette_scan::direction_from_deflection;
use harvest_hw::lidar::{LidarSpec, OPTICAL_FROM_LIDAR};
use harvest_ipc::camera_model::RigidTransform;
use harvest_ipc::catalogue::HW_LIDAR_POINTS;
use harvest_ipc::payloads::{LidarPoint, PointCloud};
use harvest_ipc::{Context, MonotonicClock, Publisher};
use rand::SeedableRng;
use rand::rngs::SmallRng;
use rand_distr::{Distribution, Normal};
use serde::{Deserialize, Serialize};
use std::time::Duration;

use crate::alacs_device::{fill_scene, robot_from_tof_color};
use crate::orchard::World;

/// How the simulated LiDAR behaves.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LidarDeviceConfig {
    pub spec: LidarSpec,
    /// The true extrinsic: LiDAR frame -> the ToF camera's colour optical frame.
    pub camera_from_lidar: RigidTransform,
    /// Seed of the range, direction and scan-phase noise (combined with the world seed).
    pub noise_seed: u64,
}

impl Default for LidarDeviceConfig {
    fn default() -> Self {
        Self {
            spec: LidarSpec::mid70(),
            camera_from_lidar: simulated_camera_from_lidar(),
            noise_seed: 0,
        }
    }
}

/// Why the device cannot be built or serve its channel.
#[derive(Debug, thiserror::Error)]
pub enum LidarDeviceError {
    /// A configuration value is unusable (the message names it).
    #[error("simulated lidar: {0}")]
    Config(String),
    /// `hw/lidar/points` could not be opened.
    #[error(transparent)]
    Channel(#[from] harvest_ipc::error::OpenChannelError),
    /// A frame could not be loaned or sent.
    #[error(transparent)]
    Send(#[from] harvest_ipc::error::SendError),
}

/// Buckets per side of the field-of-view grid.
const GRID: usize = 48;

/// The world's objects as the LiDAR sees them, sorted into field-of-view buckets.
#[derive(Debug)]
struct RayCaster {
    /// The whole scene in the LiDAR's optical frame (z along the boresight).
    scene: AlacsScene,
    /// Per bucket, the objects whose bounding sphere may meet its rays.
    buckets: Vec<AlacsScene>,
    /// Half width of the grid in tangent-plane coordinates (`x / z`, `y / z`).
    extent: f64,
    robot_from_lidar: RigidTransform,
    next_row_x_m: f64,
    next_row_top_z_m: f64,
    ground_z_m: f64,
    next_row_reflectance: f64,
    ground_reflectance: f64,
}

/// One surface hit: range along the beam, reflectance in `[0, 1]`, cosine of incidence.
#[derive(Debug, Clone, Copy)]
struct Return {
    range_m: f64,
    reflectance: f64,
    cos_incidence: f64,
}

fn reflectance(rgb: [u8; 3]) -> f64 {
    rgb.iter().map(|&c| f64::from(c)).sum::<f64>() / (3.0 * 255.0)
}

impl RayCaster {
    fn new(half_fov_rad: f64) -> Self {
        Self {
            scene: AlacsScene::default(),
            buckets: (0..GRID * GRID).map(|_| AlacsScene::default()).collect(),
            extent: half_fov_rad.tan() * 1.02,
            robot_from_lidar: RigidTransform::IDENTITY,
            next_row_x_m: 0.0,
            next_row_top_z_m: 0.0,
            ground_z_m: 0.0,
            next_row_reflectance: 0.0,
            ground_reflectance: 0.0,
        }
    }

    /// Rebuilds the scene and buckets from the world's current state.
    fn rebuild(&mut self, world: &World, robot_from_lidar: RigidTransform, max_range_m: f64) {
        let robot_from_optical = robot_from_lidar.compose(&OPTICAL_FROM_LIDAR.inverse());
        fill_scene(
            world,
            &robot_from_optical.inverse(),
            max_range_m,
            &mut self.scene,
        );
        self.scene.background_depth_m = None;
        let background = &world.scenario().background;
        self.robot_from_lidar = robot_from_lidar;
        self.next_row_x_m = background.next_row_x_m;
        self.next_row_top_z_m = background.next_row_top_z_m;
        self.ground_z_m = background.ground_z_m;
        self.next_row_reflectance = reflectance(background.next_row_rgb);
        self.ground_reflectance = reflectance(background.ground_rgb);
        for bucket in &mut self.buckets {
            bucket.apples.clear();
            bucket.leaves.clear();
        }
        for apple in &self.scene.apples {
            for index in bucket_range(apple.centre_in_camera_m, apple.radius_m, self.extent) {
                self.buckets[index].apples.push(*apple);
            }
        }
        for leaf in &self.scene.leaves {
            for index in bucket_range(leaf.centre_in_camera_m, leaf.radius_m, self.extent) {
                self.buckets[index].leaves.push(*leaf);
            }
        }
    }

    /// The nearest surface along a unit beam direction (LiDAR frame).
    fn cast(&self, direction: [f64; 3]) -> Option<Return> {
        let mut best: Option<Return> = None;
        let mut consider = |candidate: Return| {
            if candidate.range_m > 0.0 && best.is_none_or(|b| candidate.range_m < b.range_m) {
                best = Some(candidate);
            }
        };
        let optical = OPTICAL_FROM_LIDAR.rotate(direction);
        if optical[2] > 1e-6 {
            let cell = 2.0 * self.extent / GRID as f64;
            let column = ((optical[0] / optical[2] + self.extent) / cell).floor();
            let row = ((optical[1] / optical[2] + self.extent) / cell).floor();
            if column >= 0.0 && row >= 0.0 && (column as usize) < GRID && (row as usize) < GRID {
                let bucket = &self.buckets[row as usize * GRID + column as usize];
                if let Some(hit) = bucket.ray_cast([0.0; 3], optical) {
                    let cos = -(hit.normal[0] * optical[0]
                        + hit.normal[1] * optical[1]
                        + hit.normal[2] * optical[2]);
                    consider(Return {
                        range_m: hit.t,
                        reflectance: reflectance(hit.albedo_rgb),
                        cos_incidence: cos.abs(),
                    });
                }
            }
        }
        // The backdrop planes, in the robot frame.
        let o = self.robot_from_lidar.translation_m;
        let d = self.robot_from_lidar.rotate(direction);
        if d[0] > 1e-6 {
            let t = (self.next_row_x_m - o[0]) / d[0];
            let height = o[2] + d[2] * t;
            if height >= self.ground_z_m && height <= self.next_row_top_z_m {
                consider(Return {
                    range_m: t,
                    reflectance: self.next_row_reflectance,
                    cos_incidence: d[0],
                });
            }
        }
        if d[2] < -1e-6 {
            let t = (self.ground_z_m - o[2]) / d[2];
            if o[0] + d[0] * t <= self.next_row_x_m {
                consider(Return {
                    range_m: t,
                    reflectance: self.ground_reflectance,
                    cos_incidence: -d[2],
                });
            }
        }
        best
    }
}

/// Bucket indices whose tangent-plane cells the bounding sphere `(centre, radius)` (optical
/// frame) may cover; all buckets when the sphere reaches the sensor plane.
fn bucket_range(centre: [f64; 3], radius_m: f64, extent: f64) -> impl Iterator<Item = usize> {
    let cell = 2.0 * extent / GRID as f64;
    let [cx, cy, cz] = centre;
    let span = if cz - radius_m <= 1e-3 {
        if cz + radius_m <= 0.0 {
            None
        } else {
            Some((0, GRID - 1, 0, GRID - 1))
        }
    } else {
        // Exact tangent bounds of the sphere's silhouette on the plane z = 1.
        let denominator = cz * cz - radius_m * radius_m;
        let bounds = |lateral: f64| {
            let root = radius_m * (lateral * lateral + denominator).sqrt();
            (
                (lateral * cz - root) / denominator,
                (lateral * cz + root) / denominator,
            )
        };
        let ((x0, x1), (y0, y1)) = (bounds(cx), bounds(cy));
        let index = |value: f64| ((value + extent) / cell).floor();
        let (i0, i1, j0, j1) = (index(x0), index(x1), index(y0), index(y1));
        let last = (GRID - 1) as f64;
        if i1 < 0.0 || j1 < 0.0 || i0 > last || j0 > last {
            None
        } else {
            Some((
                i0.max(0.0) as usize,
                i1.min(last) as usize,
                j0.max(0.0) as usize,
                j1.min(last) as usize,
            ))
        }
    };
    span.into_iter().flat_map(|(i0, i1, j0, j1)| {
        (j0..=j1).flat_map(move |j| (i0..=i1).map(move |i| j * GRID + i))
    })
}

/// The simulated LiDAR: scan state, noise and the ray caster.
#[derive(Debug)]
pub struct LidarDeviceServer {
    config: LidarDeviceConfig,
    scan: RosetteScan,
    rng: Option<SmallRng>,
    caster: RayCaster,
    range_noise: Normal<f64>,
    angle_noise: Normal<f64>,
    frames: u64,
}

impl LidarDeviceServer {
    pub fn new(config: LidarDeviceConfig) -> Result<Self, LidarDeviceError> {
        config.spec.validate().map_err(LidarDeviceError::Config)?;
        let t = &config.camera_from_lidar;
        if !t
            .rotation
            .iter()
            .flatten()
            .chain(&t.translation_m)
            .all(|v| v.is_finite())
        {
            return Err(LidarDeviceError::Config(format!(
                "camera_from_lidar {t:?} has non-finite entries"
            )));
        }
        let to_error = |error: rand_distr::NormalError| LidarDeviceError::Config(error.to_string());
        Ok(Self {
            scan: RosetteScan::new(&config.spec),
            rng: None,
            caster: RayCaster::new(config.spec.half_fov_rad()),
            range_noise: Normal::new(0.0, config.spec.range_sigma_m).map_err(to_error)?,
            angle_noise: Normal::new(0.0, config.spec.angular_sigma_deg.to_radians())
                .map_err(to_error)?,
            frames: 0,
            config,
        })
    }

    pub fn config(&self) -> &LidarDeviceConfig {
        &self.config
    }

    /// Frames delivered so far.
    pub fn frames(&self) -> u64 {
        self.frames
    }

    /// Pose of the LiDAR in the robot frame: the ToF colour sensor's pose composed with the
    /// mounting.
    pub fn robot_from_lidar(&self, world: &World) -> RigidTransform {
        robot_from_tof_color(world).compose(&self.config.camera_from_lidar)
    }

    /// Scans the next `count` returns of the pattern against the world in its current state and
    /// appends the reported points (LiDAR frame) to `cloud`; returns how many were reported.
    pub fn scan_into(&mut self, world: &World, count: usize, cloud: &mut PointCloud) -> usize {
        let before = cloud.meta.point_count;
        self.scan_firings(world, count, |point| match point {
            Some(point) => cloud.push(point),
            None => true,
        });
        (cloud.meta.point_count - before) as usize
    }

    /// Scans the next `count` firings of the pattern against the world in its current state and
    /// hands each to `each` in firing order: the point (LiDAR frame), or None when the firing
    /// reports nothing (no surface, or outside the working range). Stops early when `each`
    /// returns false (the scan then resumes at the next firing).
    pub fn scan_firings(
        &mut self,
        world: &World,
        count: usize,
        mut each: impl FnMut(Option<LidarPoint>) -> bool,
    ) {
        let spec = self.config.spec;
        let robot_from_lidar = self.robot_from_lidar(world);
        self.caster
            .rebuild(world, robot_from_lidar, spec.range_m[1]);
        let seed = self.config.noise_seed ^ world.seed().wrapping_mul(0x9e37_79b9_7f4a_7c15);
        let rng = self
            .rng
            .get_or_insert_with(|| SmallRng::seed_from_u64(seed));
        for _ in 0..count {
            let [dy, dz] = self.scan.next_deflection_rad();
            let direction = direction_from_deflection([
                dy + self.angle_noise.sample(rng),
                dz + self.angle_noise.sample(rng),
            ]);
            let point = self.caster.cast(direction).and_then(|hit| {
                if hit.range_m < spec.range_m[0] || hit.range_m > spec.range_m[1] {
                    return None;
                }
                let range_m = hit.range_m + self.range_noise.sample(rng);
                let intensity = 150.0 * hit.reflectance * (0.3 + 0.7 * hit.cos_incidence.min(1.0));
                Some(LidarPoint {
                    x_m: (direction[0] * range_m) as f32,
                    y_m: (direction[1] * range_m) as f32,
                    z_m: (direction[2] * range_m) as f32,
                    intensity: intensity as f32,
                })
            });
            if !each(point) {
                break;
            }
        }
    }

    /// One device frame (`1 / frame_rate` of returns) into `cloud`, replacing its points and
    /// setting `meta.integration_ns`; the caller stamps `header.capture_ns`.
    pub fn capture_frame(&mut self, world: &World, cloud: &mut PointCloud) -> usize {
        cloud.clear();
        let spec = self.config.spec;
        let points = self.scan_into(world, spec.points_per_frame(), cloud);
        cloud.meta.integration_ns = (1e9 / spec.frame_rate_hz) as u64;
        self.frames += 1;
        tracing::trace!(frame = self.frames, points, "lidar frame scanned");
        points
    }
}

/// The simulated LiDAR on its hardware channel: one scanned frame per tick on
/// `hw/lidar/points`, written in place into the loaned sample.
pub struct LidarDevicePort {
    server: LidarDeviceServer,
    frames_out: Publisher<PointCloud>,
}

impl LidarDevicePort {
    pub fn open(context: &Context, config: LidarDeviceConfig) -> Result<Self, LidarDeviceError> {
        let server = LidarDeviceServer::new(config)?;
        let frames_out = context.publisher(HW_LIDAR_POINTS)?;
        Ok(Self { server, frames_out })
    }

    /// Period of the device's frames.
    pub fn period(&self) -> Duration {
        Duration::from_secs_f64(1.0 / self.server.config.spec.frame_rate_hz)
    }

    /// Scans the next frame against the world and publishes it (capture time = end of the
    /// frame's window, now).
    pub fn tick(&mut self, world: &World) -> Result<(), LidarDeviceError> {
        let mut frame = self.frames_out.loan()?;
        self.server.capture_frame(world, &mut frame);
        frame.header.capture_ns = MonotonicClock::read_ns();
        self.frames_out.send(frame)?;
        Ok(())
    }
}

/// The unit as the simulator builds it: the CAD pose off by a plausible assembly error
/// (about 0.5-1 deg and a few millimetres per axis). The calibration must recover this one.
pub fn simulated_camera_from_lidar() -> RigidTransform {
    let error = RigidTransform::from_rpy_translation(
        0.6_f64.to_radians(),
        -0.8_f64.to_radians(),
        0.5_f64.to_radians(),
        [0.004, -0.006, 0.003],
    );
    error.compose(&harvest_hw::lidar::CAD_CAMERA_FROM_LIDAR)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::Scenario;

    fn world(preset: &str) -> World {
        World::generate(&Scenario::preset(preset).expect("preset"), 4).expect("world")
    }

    #[test]
    fn returns_lie_on_the_apples_leaves_and_backdrop_of_the_world() {
        let world = world("ideal");
        let mut device = LidarDeviceServer::new(LidarDeviceConfig {
            spec: LidarSpec {
                range_sigma_m: 0.0,
                angular_sigma_deg: 0.0,
                ..LidarSpec::mid70()
            },
            ..LidarDeviceConfig::default()
        })
        .expect("device");
        let mut cloud: Box<PointCloud> = harvest_ipc::payload::boxed_zeroed();
        cloud.clear();
        let reported = device.scan_into(&world, 50_000, &mut cloud);
        assert!(reported > 20_000, "{reported} returns");
        let robot_from_lidar = device.robot_from_lidar(&world);
        let background = &world.scenario().background;
        let mut on_apples = 0;
        for point in cloud.valid_points() {
            let p = robot_from_lidar.apply(point.position_m().map(f64::from));
            let on_apple = world.apples().iter().any(|apple| {
                let d: f64 = (0..3)
                    .map(|k| (p[k] - apple.center_in_robot_m[k]).powi(2))
                    .sum::<f64>()
                    .sqrt();
                (d - apple.radius_m).abs() < 1e-4
            });
            let on_row = (p[0] - background.next_row_x_m).abs() < 1e-4;
            let on_ground = (p[2] - background.ground_z_m).abs() < 1e-4;
            let on_leaf = world.leaves().iter().any(|leaf| {
                let offset: [f64; 3] = std::array::from_fn(|k| p[k] - leaf.center_in_robot_m[k]);
                let along: f64 = (0..3).map(|k| offset[k] * leaf.normal_in_robot[k]).sum();
                let radius = (leaf.half_length_m * leaf.half_width_m).sqrt();
                along.abs() < 1e-4
                    && offset.iter().map(|o| o * o).sum::<f64>() <= radius * radius + 1e-6
            });
            assert!(
                on_apple || on_row || on_ground || on_leaf,
                "stray point {p:?}"
            );
            on_apples += usize::from(on_apple);
        }
        assert!(on_apples > 100, "{on_apples} returns on apples");
    }

    #[test]
    fn frames_hold_a_tenth_of_a_second_and_range_noise_matches_the_spec() {
        let mut scenario = Scenario::preset("ideal").expect("ideal");
        scenario.apples.count = 0;
        let world = World::generate(&scenario, 2).expect("world");
        let mut device = LidarDeviceServer::new(LidarDeviceConfig {
            spec: LidarSpec {
                angular_sigma_deg: 0.0,
                ..LidarSpec::mid70()
            },
            ..LidarDeviceConfig::default()
        })
        .expect("device");
        let mut cloud: Box<PointCloud> = harvest_ipc::payload::boxed_zeroed();
        device.capture_frame(&world, &mut cloud);
        assert_eq!(cloud.meta.integration_ns, 100_000_000);
        assert!(cloud.valid_points().len() <= 10_000);
        // Range error against the exact backdrop along each beam.
        let (mut sum, mut sum_sq, mut n) = (0.0, 0.0, 0.0);
        for point in cloud.valid_points() {
            let p = point.position_m().map(f64::from);
            let range = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
            let direction = p.map(|c| c / range);
            let Some(exact) = device.caster.cast(direction) else {
                continue;
            };
            // Beams near a plane edge may switch surface under noise: skip gross differences.
            let error = range - exact.range_m;
            if error.abs() > 0.2 {
                continue;
            }
            sum += error;
            sum_sq += error * error;
            n += 1.0;
        }
        let mean = sum / n;
        let std = (sum_sq / n - mean * mean).sqrt();
        assert!(n > 5_000.0, "{n} returns");
        assert!(mean.abs() < 0.002, "mean range error {mean} m");
        assert!((std / 0.02 - 1.0).abs() < 0.05, "range sigma {std} m");
    }
}

#[cfg(test)]
mod extrinsic_file_tests {
    use super::simulated_camera_from_lidar;
    use harvest_ipc::camera_model::RigidTransform;

    /// The extrinsic the simulated robot's launch profiles pass to perception
    /// (`--lidar-extrinsic sim/lidar_extrinsic.toml`) is the one the simulator builds with.
    #[test]
    fn lidar_extrinsic_file_matches_the_simulated_unit() {
        #[derive(serde::Deserialize)]
        struct File {
            camera_from_lidar: RigidTransform,
        }
        let text = include_str!("../lidar_extrinsic.toml");
        let file: File = toml::from_str(text).expect("sim/lidar_extrinsic.toml parses");
        let truth = simulated_camera_from_lidar();
        if std::env::var_os("HARVEST_PRINT_SIM_EXTRINSIC").is_some() {
            println!("{}", toml::to_string(&truth).expect("encode"));
        }
        for row in 0..3 {
            for column in 0..3 {
                let difference =
                    file.camera_from_lidar.rotation[row][column] - truth.rotation[row][column];
                assert!(difference.abs() < 1e-12, "rotation [{row}][{column}]");
            }
            let difference = file.camera_from_lidar.translation_m[row] - truth.translation_m[row];
            assert!(difference.abs() < 1e-12, "translation [{row}]");
        }
    }
}
