//! Checkerboard corners in a LiDAR point cloud ([fusion sec. II-C-1, eq. 4-5]).
//!
//! The paper (after ACSC) finds the corners by fitting a template of the board to the points:
//! the pose of the template that maximizes the agreement of the points with it, where a point
//! counts when it falls inside the board (`sigma(p)`) and its intensity class matches the
//! template's colour there (`sigma(I_S, I_P)`). Here:
//! 1. the board plane is fitted to the measured ranges (the LiDAR errs along its beams: weighted
//!    least squares on inverse ranges, two rounds of 3-sigma rejection on range residuals);
//! 2. every point is moved along its own beam onto the plane: the beam direction is precise
//!    (0.05 deg) while the range is not (2 cm), so this removes the range noise from the
//!    in-plane position;
//! 3. intensities are split into dark and bright by two-class k-means;
//! 4. the in-plane pose `(t_x, t_y, theta)` of the template that maximizes the agreement count of
//!    eq. 4: an exhaustive grid around the level pose centred on the points' extent (+-6 cm,
//!    +-15 deg, on a subsample), then local grids refined down to 0.15 mm and 0.015 deg;
//! 5. the template's inner corners are mapped back to the LiDAR frame.
//!
//! Corner order follows the board frame convention (x to the sensors' right, y down), which
//! also fixes the board's 180-degree symmetry: the LiDAR is upright like the camera.
//! The distance weighting `d(p, G)` of eq. 5 is not used: with every point on the board the
//! plain agreement count already peaks at the true pose.

use crate::lidar::checkerboard::Checkerboard;
use harvest_ipc::payloads::LidarPoint;
use nalgebra::{Matrix3, SymmetricEigen, Vector3};

/// Corners found in one cloud.
#[derive(Debug, Clone, PartialEq)]
pub struct BoardDetection {
    /// Inner corners in the LiDAR frame, row by row like [`Checkerboard::corners_m`], metres.
    pub corners_in_lidar_m: Vec<[f64; 3]>,
    /// Board points used after plane fitting.
    pub points_used: usize,
    /// RMS distance of the used points from the fitted plane, metres.
    pub plane_rms_m: f64,
    /// Share of the used points that agree with the fitted template (eq. 4 over the count).
    pub template_agreement: f64,
    /// Distance of the board centre from the LiDAR, metres.
    pub distance_m: f64,
}

/// Why no corners were found.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CornerError {
    /// Too few finite points to fit the board.
    #[error("only {found} finite points on the board, need at least {needed}")]
    TooFewPoints { found: usize, needed: usize },
    /// The points do not form a plane (or form a line).
    #[error("board points do not span a plane (eigenvalues {eigenvalues:?})")]
    NotPlanar { eigenvalues: [f64; 3] },
    /// Dark and bright returns cannot be told apart.
    #[error(
        "no intensity contrast on the board: dark mean {dark:.1}, bright mean {bright:.1} \
         (need a difference of at least {needed:.1})"
    )]
    NoContrast { dark: f32, bright: f32, needed: f32 },
    /// The best template pose still disagrees with many points.
    #[error("template fits only {agreement:.2} of the board points (need {needed:.2})")]
    PoorFit { agreement: f64, needed: f64 },
}

/// Minimum points to attempt a detection.
pub const MIN_BOARD_POINTS: usize = 300;
/// Points used in the template search (a deterministic subsample of larger clouds).
const MAX_SEARCH_POINTS: usize = 20_000;
/// Points used in the exhaustive coarse search.
const COARSE_SEARCH_POINTS: usize = 2_000;
/// Minimum intensity difference between the two classes.
const MIN_CONTRAST: f32 = 10.0;
/// Minimum share of points agreeing with the fitted template.
const MIN_AGREEMENT: f64 = 0.7;

/// Finds the inner corners of `board` in `points` (LiDAR frame; the board's points, as when the
/// board hangs in the air in front of an empty background).
pub fn detect_board_corners(
    points: &[LidarPoint],
    board: &Checkerboard,
) -> Result<BoardDetection, CornerError> {
    let finite: Vec<([f64; 3], f32)> = points
        .iter()
        .filter(|p| p.is_finite() && p.intensity.is_finite())
        .map(|p| (p.position_m().map(f64::from), p.intensity))
        .collect();
    if finite.len() < MIN_BOARD_POINTS {
        return Err(CornerError::TooFewPoints {
            found: finite.len(),
            needed: MIN_BOARD_POINTS,
        });
    }
    // 1. Plane from the ranges, with outlier rejection on the range residuals.
    check_extent(&finite)?;
    let mut inliers: Vec<usize> = (0..finite.len()).collect();
    let mut plane = fit_plane_along_beams(&finite, &inliers)?;
    for _ in 0..2 {
        let limit = (3.0 * plane.rms_m).max(0.01);
        inliers.retain(|&k| plane.range_residual_m(finite[k].0).abs() <= limit);
        if inliers.len() < MIN_BOARD_POINTS {
            return Err(CornerError::TooFewPoints {
                found: inliers.len(),
                needed: MIN_BOARD_POINTS,
            });
        }
        plane = fit_plane_along_beams(&finite, &inliers)?;
    }
    // 2. In-plane basis: x level (perpendicular to the LiDAR's up, +z) and to the sensor's right,
    // y down the board, normal away from the sensor: a board hung level has theta = 0.
    let normal = plane.normal;
    let level = cross(normal, [0.0, 0.0, 1.0]);
    if dot(level, level) < 1e-6 {
        return Err(CornerError::NotPlanar {
            eigenvalues: [0.0; 3],
        });
    }
    let e_x = normalize(level);
    let e_y = cross(normal, e_x);
    let origin = plane.centroid;
    let n_dot_c = plane.offset_m;
    let stride = inliers.len().div_ceil(MAX_SEARCH_POINTS);
    let mut flat: Vec<([f64; 2], f32)> = Vec::with_capacity(inliers.len() / stride + 1);
    for &k in inliers.iter().step_by(stride) {
        let (p, intensity) = finite[k];
        let facing = dot(p, normal);
        if facing.abs() < 1e-9 {
            continue;
        }
        // Along the beam onto the plane.
        let on_plane = p.map(|c| c * n_dot_c / facing);
        let offset: [f64; 3] = std::array::from_fn(|i| on_plane[i] - origin[i]);
        flat.push(([dot(offset, e_x), dot(offset, e_y)], intensity));
    }
    // 3. Dark / bright classes.
    let (dark, bright) = two_means(flat.iter().map(|(_, i)| *i));
    if bright - dark < MIN_CONTRAST {
        return Err(CornerError::NoContrast {
            dark,
            bright,
            needed: MIN_CONTRAST,
        });
    }
    let threshold = (dark + bright) / 2.0;
    let samples: Vec<([f64; 2], bool)> = flat
        .iter()
        .map(|(q, intensity)| (*q, *intensity > threshold))
        .collect();
    // 4. Template pose: the middle of the points' extent, level; then an exhaustive coarse
    // search on a subsample (the score has a local maximum at every two-square shift, so a
    // local search from a rough start is not enough) and local refinement on all points.
    let initial = initial_pose(&samples);
    let coarse_stride = samples.len().div_ceil(COARSE_SEARCH_POINTS);
    let coarse: Vec<([f64; 2], bool)> = samples.iter().step_by(coarse_stride).copied().collect();
    let mut pose = initial;
    let mut best = 0;
    for c in -15..=15 {
        for a in -12..=12 {
            for b in -12..=12 {
                let candidate = [
                    initial[0] + a as f64 * 0.005,
                    initial[1] + b as f64 * 0.005,
                    initial[2] + (c as f64).to_radians(),
                ];
                let value = agreement(&coarse, board, candidate);
                if value > best {
                    best = value;
                    pose = candidate;
                }
            }
        }
    }
    let score = |pose: [f64; 3]| agreement(&samples, board, pose);
    let mut best = score(pose);
    for (step_m, step_rad) in [
        (0.0025, 0.25_f64.to_radians()),
        (0.0006, 0.06_f64.to_radians()),
        (0.00015, 0.015_f64.to_radians()),
    ] {
        let centre = pose;
        for a in -4..=4 {
            for b in -4..=4 {
                for c in -4..=4 {
                    let candidate = [
                        centre[0] + a as f64 * step_m,
                        centre[1] + b as f64 * step_m,
                        centre[2] + c as f64 * step_rad,
                    ];
                    let value = score(candidate);
                    if value > best {
                        best = value;
                        pose = candidate;
                    }
                }
            }
        }
    }
    let template_agreement = best as f64 / samples.len() as f64;
    if template_agreement < MIN_AGREEMENT {
        return Err(CornerError::PoorFit {
            agreement: template_agreement,
            needed: MIN_AGREEMENT,
        });
    }
    // 5. Corners back to the LiDAR frame.
    let (sin, cos) = pose[2].sin_cos();
    let corners_in_lidar_m = board
        .corners_m()
        .into_iter()
        .map(|[x, y]| {
            let qx = pose[0] + cos * x - sin * y;
            let qy = pose[1] + sin * x + cos * y;
            std::array::from_fn(|k| origin[k] + qx * e_x[k] + qy * e_y[k])
        })
        .collect();
    let centre: [f64; 3] = std::array::from_fn(|k| origin[k] + pose[0] * e_x[k] + pose[1] * e_y[k]);
    Ok(BoardDetection {
        corners_in_lidar_m,
        points_used: inliers.len(),
        plane_rms_m: plane.rms_m,
        template_agreement,
        distance_m: dot(centre, centre).sqrt(),
    })
}

/// A fitted plane `normal . x = offset_m` (normal away from the sensor) and the centroid of the
/// points moved along their beams onto it.
#[derive(Debug, Clone, Copy)]
struct Plane {
    normal: [f64; 3],
    offset_m: f64,
    centroid: [f64; 3],
    /// RMS range residual of the fitted points, metres.
    rms_m: f64,
}

impl Plane {
    /// Measured range minus the range at which the point's beam meets the plane, metres.
    fn range_residual_m(&self, p: [f64; 3]) -> f64 {
        let range = dot(p, p).sqrt();
        let facing = dot(p, self.normal) / range;
        if facing <= 1e-9 {
            return f64::INFINITY;
        }
        range - self.offset_m / facing
    }
}

/// The board must extend in two directions (not a line, not a blob): PCA of the points.
fn check_extent(points: &[([f64; 3], f32)]) -> Result<(), CornerError> {
    let n = points.len() as f64;
    let mut centroid = Vector3::zeros();
    for (p, _) in points {
        centroid += Vector3::from(*p) / n;
    }
    let mut covariance = Matrix3::<f64>::zeros();
    for (p, _) in points {
        let d = Vector3::from(*p) - centroid;
        covariance += d * d.transpose() / n;
    }
    let mut eigenvalues: [f64; 3] = SymmetricEigen::new(covariance).eigenvalues.into();
    eigenvalues.sort_by(f64::total_cmp);
    // Two spreads of at least 2 cm (standard deviation), and flatter than wide.
    if eigenvalues[1] < 4e-4 || eigenvalues[0] > 0.5 * eigenvalues[1] {
        return Err(CornerError::NotPlanar { eigenvalues });
    }
    Ok(())
}

/// The plane that best explains the measured *ranges*: the LiDAR's error is along its beams, so
/// an orthogonal (PCA) fit would tilt towards the beams on an oblique board. With the plane
/// written `m . x = 1`, a beam `u` meets it at range `1 / (m . u)`, so the inverse ranges are
/// linear in `m`: weighted least squares `min sum r^4 (1 / r_i - m . u_i)^2` (the weight turns
/// inverse-range residuals back into range residuals).
fn fit_plane_along_beams(
    points: &[([f64; 3], f32)],
    indices: &[usize],
) -> Result<Plane, CornerError> {
    let mut normal_matrix = Matrix3::<f64>::zeros();
    let mut rhs = Vector3::<f64>::zeros();
    for &k in indices {
        let p = Vector3::from(points[k].0);
        let range = p.norm();
        let u = p / range;
        let weight = range.powi(4);
        normal_matrix += weight * u * u.transpose();
        rhs += weight * u / range;
    }
    let not_planar = || {
        let mut eigenvalues: [f64; 3] = SymmetricEigen::new(normal_matrix).eigenvalues.into();
        eigenvalues.sort_by(f64::total_cmp);
        CornerError::NotPlanar { eigenvalues }
    };
    let m = normal_matrix
        .cholesky()
        .map(|c| c.solve(&rhs))
        .ok_or_else(not_planar)?;
    let scale = m.norm();
    if !(scale.is_finite() && scale > 0.0) {
        return Err(not_planar());
    }
    let normal = [m[0] / scale, m[1] / scale, m[2] / scale];
    let offset_m = 1.0 / scale;
    let mut plane = Plane {
        normal,
        offset_m,
        centroid: [0.0; 3],
        rms_m: 0.0,
    };
    let n = indices.len() as f64;
    let mut sum_sq = 0.0;
    for &k in indices {
        let p = points[k].0;
        let residual = plane.range_residual_m(p);
        sum_sq += residual * residual;
        let facing = dot(p, normal);
        if facing > 1e-9 {
            for (c, v) in plane.centroid.iter_mut().zip(p) {
                *c += v * offset_m / facing / n;
            }
        }
    }
    plane.rms_m = (sum_sq / n).sqrt();
    if !plane.rms_m.is_finite() {
        return Err(not_planar());
    }
    Ok(plane)
}

/// Two-class k-means on intensities: `(dark mean, bright mean)`.
fn two_means(values: impl Iterator<Item = f32> + Clone) -> (f32, f32) {
    let (mut low, mut high) = values
        .clone()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    for _ in 0..20 {
        let threshold = (low + high) / 2.0;
        let (mut sum_low, mut n_low, mut sum_high, mut n_high) = (0.0f64, 0usize, 0.0f64, 0usize);
        for v in values.clone() {
            if v > threshold {
                sum_high += f64::from(v);
                n_high += 1;
            } else {
                sum_low += f64::from(v);
                n_low += 1;
            }
        }
        if n_low == 0 || n_high == 0 {
            break;
        }
        low = (sum_low / n_low as f64) as f32;
        high = (sum_high / n_high as f64) as f32;
    }
    (low, high)
}

/// Initial `(t_x, t_y, theta)`: the middle of the points' extent along the plane axes, level
/// (the board hangs with its lower edge parallel to the ground; `theta = 0`).
fn initial_pose(samples: &[([f64; 2], bool)]) -> [f64; 3] {
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for (q, _) in samples {
        lo = [lo[0].min(q[0]), lo[1].min(q[1])];
        hi = [hi[0].max(q[0]), hi[1].max(q[1])];
    }
    [(lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0, 0.0]
}

/// Eq. 4 as a count: points inside the board whose intensity class matches the template colour
/// at the template pose `(t_x, t_y, theta)`.
fn agreement(samples: &[([f64; 2], bool)], board: &Checkerboard, pose: [f64; 3]) -> usize {
    let (sin, cos) = pose[2].sin_cos();
    samples
        .iter()
        .filter(|(q, bright)| {
            let (dx, dy) = (q[0] - pose[0], q[1] - pose[1]);
            let x = cos * dx + sin * dy;
            let y = -sin * dx + cos * dy;
            board.is_white(x, y) == Some(*bright)
        })
        .count()
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn normalize(a: [f64; 3]) -> [f64; 3] {
    let norm = dot(a, a).sqrt();
    a.map(|v| v / norm)
}
