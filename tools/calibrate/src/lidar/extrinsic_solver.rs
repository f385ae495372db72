//! The extrinsic `T_L^C` (camera_from_lidar) that minimizes the reprojection error of matched
//! LiDAR points and image pixels ([fusion eq. 3]):
//! `min sum_i || p_uv,i - pi(K T_L^C L_p_i) ||^2`, by Levenberg-Marquardt from an initial guess
//! (the CAD transform).
//!
//! Parametrization: `T = Exp(delta) * T_0` with `delta = (rotation vector, translation)` applied
//! on the left (in the camera frame), re-linearized at every accepted step. The Jacobian is
//! taken by central differences (six parameters, a few hundred residuals: cheap).
//!
//! Degenerate inputs are refused before solving: too few correspondences, and correspondences
//! that are all coplanar (a single board placement, or every board in one plane), which leave the
//! translation along the viewing direction nearly unobservable; after solving, a normal matrix
//! whose scaled condition number is too large is refused too.

use harvest_ipc::camera_model::{CameraIntrinsics, RigidTransform};
use nalgebra::{Matrix3, Matrix6, Rotation3, SymmetricEigen, Vector3, Vector6};

/// One matched pair: a LiDAR point and its pixel in the image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Correspondence {
    /// The feature in the LiDAR frame, metres.
    pub point_in_lidar_m: [f64; 3],
    /// The same feature detected in the image, pixels.
    pub pixel: [f64; 2],
}

/// Solver settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SolverConfig {
    pub max_iterations: usize,
    /// Minimum number of correspondences.
    pub min_correspondences: usize,
    /// Correspondences whose points lie within this RMS distance of one plane are coplanar, m.
    pub coplanar_rms_m: f64,
    /// Largest accepted condition number of the scaled normal matrix.
    pub max_condition: f64,
}

impl Default for SolverConfig {
    fn default() -> Self {
        Self {
            max_iterations: 100,
            min_correspondences: 12,
            coplanar_rms_m: 0.01,
            max_condition: 1e8,
        }
    }
}

/// The solution.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ExtrinsicSolution {
    pub camera_from_lidar: RigidTransform,
    pub iterations: usize,
    /// RMS reprojection error at the initial guess and at the solution, pixels.
    pub initial_rms_px: f64,
    pub final_rms_px: f64,
    /// Scaled condition number of the normal matrix at the solution.
    pub condition: f64,
}

/// Why no extrinsic was computed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SolveError {
    #[error("{found} correspondences, need at least {needed}: detect more corners or add views")]
    TooFewCorrespondences { found: usize, needed: usize },
    #[error("correspondence {index} is not finite: {point:?} -> {pixel:?}")]
    NonFinite {
        index: usize,
        point: [f64; 3],
        pixel: [f64; 2],
    },
    #[error(
        "all {count} correspondences lie on one plane (RMS {rms_m:.4} m off it): a single \
         board placement cannot fix the extrinsic; place the board at other distances and angles"
    )]
    Coplanar { count: usize, rms_m: f64 },
    #[error(
        "{behind} of {count} points are behind the camera at the initial guess: check the CAD \
         extrinsic"
    )]
    BehindCamera { behind: usize, count: usize },
    #[error(
        "the problem is ill-conditioned (scaled condition number {condition:.3e} > {limit:.1e}): \
         spread the board placements over the field of view and over distance"
    )]
    IllConditioned { condition: f64, limit: f64 },
}

/// Applies `Exp(delta)` on the left of `base`.
pub fn perturb(base: &RigidTransform, delta: &Vector6<f64>) -> RigidTransform {
    let rotation = Rotation3::from_scaled_axis(Vector3::new(delta[0], delta[1], delta[2]));
    let m = rotation.matrix();
    let left = RigidTransform {
        rotation: std::array::from_fn(|i| std::array::from_fn(|j| m[(i, j)])),
        translation_m: [delta[3], delta[4], delta[5]],
    };
    left.compose(base)
}

/// Rotation angle between two transforms' rotations, radians.
pub fn rotation_error_rad(a: &RigidTransform, b: &RigidTransform) -> f64 {
    let relative = a.compose(&b.inverse());
    let r = relative.rotation;
    ((r[0][0] + r[1][1] + r[2][2] - 1.0) / 2.0)
        .clamp(-1.0, 1.0)
        .acos()
}

/// Distance between two transforms' translations, metres.
pub fn translation_error_m(a: &RigidTransform, b: &RigidTransform) -> f64 {
    (0..3)
        .map(|k| (a.translation_m[k] - b.translation_m[k]).powi(2))
        .sum::<f64>()
        .sqrt()
}

/// Reprojection residual `pi(K T p) - p_uv` of one correspondence; `None` behind the camera.
pub fn residual(
    intrinsics: &CameraIntrinsics,
    camera_from_lidar: &RigidTransform,
    correspondence: &Correspondence,
) -> Option<[f64; 2]> {
    let (u, v) = intrinsics.project(camera_from_lidar.apply(correspondence.point_in_lidar_m))?;
    Some([u - correspondence.pixel[0], v - correspondence.pixel[1]])
}

/// Penalty residual for a point that falls behind the camera during the search, pixels.
const BEHIND_PENALTY_PX: f64 = 1e4;

fn residuals(
    intrinsics: &CameraIntrinsics,
    transform: &RigidTransform,
    correspondences: &[Correspondence],
    out: &mut Vec<f64>,
) {
    out.clear();
    for c in correspondences {
        let r = residual(intrinsics, transform, c).unwrap_or([BEHIND_PENALTY_PX; 2]);
        out.extend_from_slice(&r);
    }
}

fn sum_sq(r: &[f64]) -> f64 {
    r.iter().map(|v| v * v).sum()
}

/// Solves eq. 3 from `initial` (the CAD extrinsic).
pub fn solve_extrinsic(
    intrinsics: &CameraIntrinsics,
    correspondences: &[Correspondence],
    initial: &RigidTransform,
    config: &SolverConfig,
) -> Result<ExtrinsicSolution, SolveError> {
    check_input(intrinsics, correspondences, initial, config)?;
    let n = correspondences.len();
    let mut transform = *initial;
    let mut r = Vec::with_capacity(2 * n);
    residuals(intrinsics, &transform, correspondences, &mut r);
    let initial_rms_px = (sum_sq(&r) / n as f64).sqrt();
    let mut cost = sum_sq(&r);
    let mut lambda = 1e-3;
    let mut jacobian = vec![[0.0f64; 6]; 2 * n];
    let (mut plus, mut minus) = (Vec::with_capacity(2 * n), Vec::with_capacity(2 * n));
    let mut iterations = 0;
    let mut normal = Matrix6::<f64>::zeros();
    for iteration in 0..config.max_iterations {
        iterations = iteration + 1;
        // Central-difference Jacobian of the residuals w.r.t. delta at 0.
        for p in 0..6 {
            let h = 1e-6;
            let mut delta = Vector6::zeros();
            delta[p] = h;
            residuals(
                intrinsics,
                &perturb(&transform, &delta),
                correspondences,
                &mut plus,
            );
            delta[p] = -h;
            residuals(
                intrinsics,
                &perturb(&transform, &delta),
                correspondences,
                &mut minus,
            );
            for (row, (a, b)) in jacobian.iter_mut().zip(plus.iter().zip(&minus)) {
                row[p] = (a - b) / (2.0 * h);
            }
        }
        normal = Matrix6::zeros();
        let mut gradient = Vector6::<f64>::zeros();
        for (row, residual) in jacobian.iter().zip(&r) {
            let j = Vector6::from_row_slice(row);
            normal += j * j.transpose();
            gradient += j * *residual;
        }
        let mut improved = false;
        for _ in 0..20 {
            let mut damped = normal;
            for k in 0..6 {
                damped[(k, k)] += lambda * normal[(k, k)].max(1e-12);
            }
            let Some(step) = damped.cholesky().map(|c| c.solve(&(-gradient))) else {
                lambda *= 10.0;
                continue;
            };
            let candidate = perturb(&transform, &step);
            residuals(intrinsics, &candidate, correspondences, &mut plus);
            let candidate_cost = sum_sq(&plus);
            if candidate_cost < cost {
                let relative = (cost - candidate_cost) / cost.max(1e-300);
                transform = candidate;
                std::mem::swap(&mut r, &mut plus);
                cost = candidate_cost;
                lambda = (lambda / 3.0).max(1e-12);
                improved = relative > 1e-14 && step.norm() > 1e-12;
                break;
            }
            lambda *= 4.0;
        }
        if !improved {
            break;
        }
    }
    let condition = scaled_condition(&normal);
    if condition.is_nan() || condition > config.max_condition {
        return Err(SolveError::IllConditioned {
            condition,
            limit: config.max_condition,
        });
    }
    let final_rms_px = (cost / n as f64).sqrt();
    tracing::debug!(
        iterations,
        initial_rms_px,
        final_rms_px,
        condition,
        "extrinsic solved"
    );
    Ok(ExtrinsicSolution {
        camera_from_lidar: transform,
        iterations,
        initial_rms_px,
        final_rms_px,
        condition,
    })
}

fn check_input(
    intrinsics: &CameraIntrinsics,
    correspondences: &[Correspondence],
    initial: &RigidTransform,
    config: &SolverConfig,
) -> Result<(), SolveError> {
    let count = correspondences.len();
    if count < config.min_correspondences.max(6) {
        return Err(SolveError::TooFewCorrespondences {
            found: count,
            needed: config.min_correspondences.max(6),
        });
    }
    for (index, c) in correspondences.iter().enumerate() {
        if !(c.point_in_lidar_m.iter().all(|v| v.is_finite())
            && c.pixel.iter().all(|v| v.is_finite()))
        {
            return Err(SolveError::NonFinite {
                index,
                point: c.point_in_lidar_m,
                pixel: c.pixel,
            });
        }
    }
    let rms_m = plane_rms_m(correspondences);
    if rms_m < config.coplanar_rms_m {
        return Err(SolveError::Coplanar { count, rms_m });
    }
    let behind = correspondences
        .iter()
        .filter(|c| residual(intrinsics, initial, c).is_none())
        .count();
    if behind > 0 {
        return Err(SolveError::BehindCamera { behind, count });
    }
    Ok(())
}

/// RMS distance of the points from their least-squares plane, metres.
fn plane_rms_m(correspondences: &[Correspondence]) -> f64 {
    let n = correspondences.len() as f64;
    let mut centroid = Vector3::zeros();
    for c in correspondences {
        centroid += Vector3::from(c.point_in_lidar_m) / n;
    }
    let mut covariance = Matrix3::<f64>::zeros();
    for c in correspondences {
        let d = Vector3::from(c.point_in_lidar_m) - centroid;
        covariance += d * d.transpose() / n;
    }
    let smallest = SymmetricEigen::new(covariance).eigenvalues.min();
    smallest.max(0.0).sqrt()
}

/// Condition number of `D^-1/2 N D^-1/2` (`D` = diagonal of `N`), so rotation (radians) and
/// translation (metres) columns are compared on equal terms.
fn scaled_condition(normal: &Matrix6<f64>) -> f64 {
    let mut scaled = *normal;
    for i in 0..6 {
        for j in 0..6 {
            let d = (normal[(i, i)] * normal[(j, j)]).sqrt();
            scaled[(i, j)] = if d > 0.0 { normal[(i, j)] / d } else { 0.0 };
        }
    }
    let eigenvalues = SymmetricEigen::new(scaled).eigenvalues;
    let (min, max) = (eigenvalues.min(), eigenvalues.max());
    if min <= 0.0 { f64::INFINITY } else { max / min }
}

#[cfg(test)]
mod tests {
    use super::*;
    use harvest_hw::lidar::mounting::CAD_CAMERA_FROM_LIDAR;
    use harvest_sim::lidar_device::simulated_camera_from_lidar;

    /// Points on a few planes in front of the sensors and their exact pixels.
    fn exact(truth: &RigidTransform, intrinsics: &CameraIntrinsics) -> Vec<Correspondence> {
        let mut out = Vec::new();
        for (depth, tilt) in [(1.5, 0.3), (2.2, -0.2), (2.8, 0.1)] {
            for i in -3..=3 {
                for j in -2..=2 {
                    let in_camera = [
                        0.1 * i as f64 + 0.1 * tilt,
                        0.08 * j as f64,
                        depth + tilt * 0.1 * i as f64,
                    ];
                    let (u, v) = intrinsics.project(in_camera).expect("in front");
                    out.push(Correspondence {
                        point_in_lidar_m: truth.inverse().apply(in_camera),
                        pixel: [u, v],
                    });
                }
            }
        }
        out
    }

    #[test]
    fn recovers_the_true_extrinsic_from_exact_data() {
        let intrinsics = CameraIntrinsics::tl460_rgb();
        let truth = simulated_camera_from_lidar();
        let data = exact(&truth, &intrinsics);
        let solution = solve_extrinsic(
            &intrinsics,
            &data,
            &CAD_CAMERA_FROM_LIDAR,
            &SolverConfig::default(),
        )
        .expect("solve");
        assert!(solution.initial_rms_px > 10.0);
        assert!(solution.final_rms_px < 1e-6, "{solution:?}");
        assert!(rotation_error_rad(&solution.camera_from_lidar, &truth) < 1e-8);
        assert!(translation_error_m(&solution.camera_from_lidar, &truth) < 1e-8);
    }

    #[test]
    fn degenerate_inputs_are_refused() {
        let intrinsics = CameraIntrinsics::tl460_rgb();
        let truth = simulated_camera_from_lidar();
        let config = SolverConfig::default();
        let data = exact(&truth, &intrinsics);
        let error = solve_extrinsic(&intrinsics, &data[..5], &truth, &config).expect_err("few");
        assert!(matches!(
            error,
            SolveError::TooFewCorrespondences { found: 5, .. }
        ));
        // One plane only: the first placement's 35 points.
        let error = solve_extrinsic(&intrinsics, &data[..35], &truth, &config).expect_err("flat");
        assert!(
            matches!(error, SolveError::Coplanar { count: 35, .. }),
            "{error}"
        );
        let mut bad = data.clone();
        bad[3].pixel[0] = f64::NAN;
        let error = solve_extrinsic(&intrinsics, &bad, &truth, &config).expect_err("nan");
        assert!(matches!(error, SolveError::NonFinite { index: 3, .. }));
        let flipped =
            RigidTransform::from_rpy_translation(0.0, std::f64::consts::PI, 0.0, [0.0; 3])
                .compose(&truth);
        let error = solve_extrinsic(&intrinsics, &data, &flipped, &config).expect_err("behind");
        assert!(matches!(error, SolveError::BehindCamera { .. }));
    }
}
