//! Synthetic calibration samples from known extrinsics, shaped like the paper's data set
//! ([alacs sec. 5.1]: 10 board positions between 0.6 and 1.2 m, 3 laser points each).
//!
//! For each board: a checkerboard of `board_height_m` at its depth, tilted at random, centred
//! where the laser line falls. The laser points lie on the board (section 4.2: the image covers
//! the whole checkerboard and the points are taken where the line crosses it), so how far they
//! spread over the image rows shrinks as the board moves away. For each of its points: a height
//! on the board (the points spread bottom to top, one band each), the 3D point where the laser
//! plane (eq. 4-5, slide home, `L = L0`) crosses the board at that height, projected to a pixel
//! (eq. 2), moved by Gaussian pixel noise (stripe extraction), normalised back (eq. 3); its
//! depth is where that noisy ray meets the board (the paper's pose-based depth) plus Gaussian
//! depth noise (pose reconstruction). A few samples then get a gross depth error (the outliers
//! RANSAC must find).
//!
//! The spread of rows matters for the comparison of section 5.1: the low-fidelity model (eq. 10)
//! drops the `v_bar tan(beta)` term, whose depth error grows with `|v_bar|` and with `z^2`, so
//! points spread over rows the board could not cover would exaggerate that model's error.

use harvest_hw::alacs::AlacsExtrinsics;
use harvest_ipc::camera_model::CameraIntrinsics;
use nalgebra::{Matrix3, Vector3};
use rand::rngs::SmallRng;
use rand::seq::index::sample as sample_indices;
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};

use harvest_laser::calibration::sample::CalibrationSample;

/// How to generate a sample set.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SampleGeneratorConfig {
    /// The extrinsics the samples obey.
    pub truth: AlacsExtrinsics,
    pub intrinsics: CameraIntrinsics,
    pub boards: usize,
    pub points_per_board: usize,
    pub nearest_board_m: f64,
    pub farthest_board_m: f64,
    /// Height of the checkerboard's laser-point area along the board, m.
    pub board_height_m: f64,
    /// Largest tilt of a board about the camera's x and y axes, rad.
    pub max_board_tilt_rad: f64,
    /// Standard deviation of the laser-point pixel position, pixels.
    pub pixel_noise_px: f64,
    /// Standard deviation of the board-pose depth, m.
    pub depth_noise_m: f64,
    /// Samples given a gross depth error.
    pub outliers: usize,
    /// Range of the gross errors' magnitude (sign random), m.
    pub outlier_min_m: f64,
    pub outlier_max_m: f64,
    pub seed: u64,
}

impl SampleGeneratorConfig {
    /// The paper's set-up: Table 1 extrinsics, 10 boards in 0.6-1.2 m, 3 points each, 0.25 px
    /// and 0.25 mm noise, 3 gross outliers of 5-25 mm. The board is 0.297 m high (an A3 sheet
    /// in landscape; the paper does not give its size): the tallest common sheet that fits in
    /// the ALACS camera's view (0.37 m high at 0.6 m) with a margin, as the whole board must.
    pub fn paper_like(intrinsics: CameraIntrinsics, seed: u64) -> Self {
        Self {
            truth: AlacsExtrinsics::paper_table1(),
            intrinsics,
            boards: 10,
            points_per_board: 3,
            nearest_board_m: 0.6,
            farthest_board_m: 1.2,
            board_height_m: 0.297,
            max_board_tilt_rad: 15_f64.to_radians(),
            pixel_noise_px: 0.25,
            depth_noise_m: 0.25e-3,
            outliers: 3,
            outlier_min_m: 0.005,
            outlier_max_m: 0.025,
            seed,
        }
    }
}

/// Generated samples with their ground truth.
#[derive(Debug, Clone, PartialEq)]
pub struct GeneratedSamples {
    pub samples: Vec<CalibrationSample>,
    /// `true` for the samples given a gross error.
    pub is_outlier: Vec<bool>,
    pub truth: AlacsExtrinsics,
}

impl GeneratedSamples {
    /// `true` for the uncorrupted samples.
    pub fn clean_mask(&self) -> Vec<bool> {
        self.is_outlier.iter().map(|outlier| !outlier).collect()
    }
}

/// Why no sample set could be generated.
#[derive(Debug, Clone, thiserror::Error, PartialEq)]
pub enum GenerateError {
    #[error("sample generator option {name} = {value} is invalid")]
    InvalidOption { name: &'static str, value: f64 },
    /// The laser line does not cross the image on a board.
    #[error("board {board} at {depth_m:.3} m: the laser line is not visible in the image")]
    LineNotVisible { board: usize, depth_m: f64 },
}

/// Attempts at placing a point inside the image before giving up on a board.
const MAX_ATTEMPTS: usize = 100;

/// Generates a sample set; the same config (seed included) gives the same samples.
pub fn generate_samples(config: &SampleGeneratorConfig) -> Result<GeneratedSamples, GenerateError> {
    validate(config)?;
    let mut rng = SmallRng::seed_from_u64(config.seed);
    let pixel_noise = Normal::new(0.0, config.pixel_noise_px)
        .map_err(|_| invalid("pixel_noise_px", config.pixel_noise_px))?;
    let depth_noise = Normal::new(0.0, config.depth_noise_m)
        .map_err(|_| invalid("depth_noise_m", config.depth_noise_m))?;
    let truth = config.truth;
    let intrinsics = config.intrinsics;
    let plane = truth.laser_plane_in_camera(0.0);
    let laser_normal = Vector3::from(plane.normal);
    let (sin_a, cos_a) = truth.alpha_rad.sin_cos();

    let mut samples = Vec::with_capacity(config.boards * config.points_per_board);
    for board in 0..config.boards {
        let fraction = if config.boards > 1 {
            board as f64 / (config.boards - 1) as f64
        } else {
            0.5
        };
        let depth_m =
            config.nearest_board_m + fraction * (config.farthest_board_m - config.nearest_board_m);
        // Board centred on the laser line at this depth, tilted at random.
        let centre = Vector3::new((depth_m * sin_a - truth.l0_m) / cos_a, 0.0, depth_m);
        let tilt_x = rng.random_range(-1.0..=1.0) * config.max_board_tilt_rad;
        let tilt_y = rng.random_range(-1.0..=1.0) * config.max_board_tilt_rad;
        let board_normal = Vector3::new(tilt_y.sin(), -tilt_x.sin(), -1.0).normalize();
        let board_offset = board_normal.dot(&centre);
        // The board's own vertical axis: the camera's y projected into the board plane.
        let down = Vector3::new(0.0, 1.0, 0.0);
        let board_down = (down - board_normal * board_normal.dot(&down)).normalize();
        for point in 0..config.points_per_board {
            let mut placed = None;
            for _ in 0..MAX_ATTEMPTS {
                // Heights spread over the board, one band per point.
                let band = config.board_height_m / config.points_per_board as f64;
                let height_m = -0.5 * config.board_height_m
                    + band * (point as f64 + rng.random_range(0.0..1.0));
                // Laser plane, board plane and the board's line at that height.
                let system = Matrix3::from_rows(&[
                    laser_normal.transpose(),
                    board_normal.transpose(),
                    board_down.transpose(),
                ]);
                let rhs = Vector3::new(
                    -plane.offset_m,
                    board_offset,
                    board_down.dot(&centre) + height_m,
                );
                let Some(point_on_board) = system.lu().solve(&rhs) else {
                    continue;
                };
                let Some((u_px, v_px)) = intrinsics.project(point_on_board.into()) else {
                    continue;
                };
                let u_noisy = u_px + pixel_noise.sample(&mut rng);
                let v_noisy = v_px + pixel_noise.sample(&mut rng);
                if !intrinsics.contains(u_noisy, v_noisy) {
                    continue;
                }
                let (u_bar, v_bar) = intrinsics.normalize(u_noisy, v_noisy);
                let ray = Vector3::new(u_bar, v_bar, 1.0);
                let z_on_board = board_offset / board_normal.dot(&ray);
                placed = Some(CalibrationSample {
                    u_bar,
                    v_bar,
                    z_m: z_on_board + depth_noise.sample(&mut rng),
                });
                break;
            }
            samples.push(placed.ok_or(GenerateError::LineNotVisible { board, depth_m })?);
        }
    }

    let mut is_outlier = vec![false; samples.len()];
    for index in sample_indices(&mut rng, samples.len(), config.outliers) {
        let magnitude = rng.random_range(config.outlier_min_m..=config.outlier_max_m);
        let sign = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
        samples[index].z_m += sign * magnitude;
        is_outlier[index] = true;
    }
    Ok(GeneratedSamples {
        samples,
        is_outlier,
        truth,
    })
}

fn invalid(name: &'static str, value: f64) -> GenerateError {
    GenerateError::InvalidOption { name, value }
}

fn validate(config: &SampleGeneratorConfig) -> Result<(), GenerateError> {
    let total = config.boards * config.points_per_board;
    if total == 0 {
        return Err(invalid("boards * points_per_board", total as f64));
    }
    if config.outliers > total {
        return Err(invalid("outliers", config.outliers as f64));
    }
    if !config.truth.is_valid() {
        return Err(invalid("truth.l0_m", config.truth.l0_m));
    }
    let checks = [
        (
            "nearest_board_m",
            config.nearest_board_m,
            config.nearest_board_m > 0.0,
        ),
        (
            "farthest_board_m",
            config.farthest_board_m,
            config.farthest_board_m >= config.nearest_board_m,
        ),
        (
            "board_height_m",
            config.board_height_m,
            config.board_height_m > 0.0,
        ),
        (
            "max_board_tilt_rad",
            config.max_board_tilt_rad,
            config.max_board_tilt_rad.abs() < 1.2,
        ),
        (
            "pixel_noise_px",
            config.pixel_noise_px,
            config.pixel_noise_px >= 0.0,
        ),
        (
            "depth_noise_m",
            config.depth_noise_m,
            config.depth_noise_m >= 0.0,
        ),
        (
            "outlier_min_m",
            config.outlier_min_m,
            config.outlier_min_m >= 0.0,
        ),
        (
            "outlier_max_m",
            config.outlier_max_m,
            config.outlier_max_m >= config.outlier_min_m,
        ),
    ];
    for (name, value, valid) in checks {
        if !valid || !value.is_finite() {
            return Err(invalid(name, value));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use harvest_hw::alacs::alacs_camera_intrinsics;

    #[test]
    fn noise_free_samples_obey_eq_7_and_span_the_depths() {
        let mut config = SampleGeneratorConfig::paper_like(alacs_camera_intrinsics(), 3);
        config.pixel_noise_px = 0.0;
        config.depth_noise_m = 0.0;
        config.outliers = 0;
        let generated = generate_samples(&config).expect("generate");
        assert_eq!(generated.samples.len(), 30);
        let truth = generated.truth;
        for sample in &generated.samples {
            let depth = harvest_laser::triangulation::high_fidelity_depth_m(
                truth.alpha_rad,
                truth.l0_m,
                truth.beta_rad,
                sample.u_bar,
                sample.v_bar,
            )
            .expect("in front");
            assert!((depth - sample.z_m).abs() < 1e-9, "{sample:?} vs {depth}");
        }
        let depths: Vec<f64> = generated.samples.iter().map(|s| s.z_m).collect();
        let min = depths.iter().copied().fold(f64::INFINITY, f64::min);
        let max = depths.iter().copied().fold(0.0, f64::max);
        assert!(min > 0.5 && max < 1.35 && max - min > 0.4, "{min} {max}");
    }

    #[test]
    fn points_lie_on_the_board_so_their_rows_narrow_with_depth() {
        let mut config = SampleGeneratorConfig::paper_like(alacs_camera_intrinsics(), 5);
        config.pixel_noise_px = 0.0;
        config.depth_noise_m = 0.0;
        config.outliers = 0;
        let generated = generate_samples(&config).expect("generate");
        let half_height_m = 0.5 * config.board_height_m;
        let mut widest_v_bar = [0.0_f64; 2];
        for (index, sample) in generated.samples.iter().enumerate() {
            // The boards are centred on the optical axis's row (y = 0): a point's height in the
            // camera frame cannot exceed half the board's height.
            let y_m = sample.v_bar * sample.z_m;
            assert!(
                y_m.abs() <= half_height_m + 1e-9,
                "sample {index}: y {y_m} m"
            );
            let board = index / config.points_per_board;
            if board == 0 {
                widest_v_bar[0] = widest_v_bar[0].max(sample.v_bar.abs());
            } else if board == config.boards - 1 {
                widest_v_bar[1] = widest_v_bar[1].max(sample.v_bar.abs());
            }
        }
        // The farthest board (1.2 m) covers at most half the rows of the nearest (0.6 m).
        assert!(
            widest_v_bar[1] <= half_height_m / 1.2 + 1e-9,
            "far board reaches v_bar {}",
            widest_v_bar[1]
        );
        assert!(widest_v_bar[0] > widest_v_bar[1], "{widest_v_bar:?}");
        let bad = SampleGeneratorConfig {
            board_height_m: 0.0,
            ..config
        };
        assert!(matches!(
            generate_samples(&bad),
            Err(GenerateError::InvalidOption {
                name: "board_height_m",
                ..
            })
        ));
    }

    #[test]
    fn outliers_are_labelled_and_seeded() {
        let config = SampleGeneratorConfig::paper_like(alacs_camera_intrinsics(), 7);
        let first = generate_samples(&config).expect("generate");
        let second = generate_samples(&config).expect("generate");
        assert_eq!(first, second);
        assert_eq!(first.is_outlier.iter().filter(|o| **o).count(), 3);
        let other =
            generate_samples(&SampleGeneratorConfig { seed: 8, ..config }).expect("generate");
        assert_ne!(first.samples, other.samples);
        let bad = SampleGeneratorConfig {
            outliers: 31,
            ..config
        };
        assert!(matches!(
            generate_samples(&bad),
            Err(GenerateError::InvalidOption {
                name: "outliers",
                ..
            })
        ));
    }
}
