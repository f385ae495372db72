//! Sphere geometry for the sphere-fit estimator: a minimal 3-point hypothesis with a radius prior
//! and a robust Gauss-Newton refinement.

use nalgebra::{Matrix3, Matrix4, SymmetricEigen, Vector3, Vector4};

use crate::noise_model::DepthNoiseModel;

/// A sphere in the camera frame, metres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Sphere {
    pub centre: [f64; 3],
    pub radius: f64,
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
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

fn norm(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}

impl Sphere {
    /// Signed distance of `p` from the surface (positive outside).
    pub(crate) fn residual(&self, p: [f64; 3]) -> f64 {
        norm(sub(p, self.centre)) - self.radius
    }

    /// True when `p` lies on the camera-facing half of the sphere (within `tolerance_m`): the
    /// visible surface of a fruit seen from the camera origin.
    pub(crate) fn faces_camera(&self, p: [f64; 3], tolerance_m: f64) -> bool {
        let distance = norm(self.centre);
        if distance <= 0.0 {
            return false;
        }
        dot(sub(p, self.centre), self.centre) / distance <= tolerance_m
    }

    pub(crate) fn is_finite(&self) -> bool {
        self.centre.iter().all(|v| v.is_finite()) && self.radius.is_finite()
    }
}

/// The sphere through `a`, `b`, `c` with radius `max(radius_prior, circumradius)` whose centre
/// lies behind the three points as seen from the camera. `None` for a degenerate triangle or a
/// circumradius above `radius_max`.
///
/// The centre is the triangle's circumcentre `o` moved along the unit normal `n` (oriented away
/// from the camera) by `h = sqrt(r^2 - rho^2)`, `rho` the circumradius.
pub(crate) fn sphere_through_three(
    a: [f64; 3],
    b: [f64; 3],
    c: [f64; 3],
    radius_prior: f64,
    radius_max: f64,
) -> Option<Sphere> {
    let ab = sub(b, a);
    let ac = sub(c, a);
    let normal = cross(ab, ac);
    let normal_sq = dot(normal, normal);
    // Reject near-collinear samples: twice the triangle area below 1 mm^2.
    if normal_sq < 1e-12 {
        return None;
    }
    let term1 = cross(normal, ab);
    let term2 = cross(ac, normal);
    let ab_sq = dot(ab, ab);
    let ac_sq = dot(ac, ac);
    let offset = [
        (ac_sq * term1[0] + ab_sq * term2[0]) / (2.0 * normal_sq),
        (ac_sq * term1[1] + ab_sq * term2[1]) / (2.0 * normal_sq),
        (ac_sq * term1[2] + ab_sq * term2[2]) / (2.0 * normal_sq),
    ];
    let circumradius = norm(offset);
    if circumradius > radius_max {
        return None;
    }
    let circumcentre = [a[0] + offset[0], a[1] + offset[1], a[2] + offset[2]];
    let radius = radius_prior.max(circumradius);
    let height = (radius * radius - circumradius * circumradius)
        .max(0.0)
        .sqrt();
    let length = normal_sq.sqrt();
    let mut unit = [normal[0] / length, normal[1] / length, normal[2] / length];
    if dot(unit, circumcentre) < 0.0 {
        unit = [-unit[0], -unit[1], -unit[2]];
    }
    let sphere = Sphere {
        centre: [
            circumcentre[0] + height * unit[0],
            circumcentre[1] + height * unit[1],
            circumcentre[2] + height * unit[2],
        ],
        radius,
    };
    sphere.is_finite().then_some(sphere)
}

/// Parameters of [`refine`].
#[derive(Debug, Clone, Copy)]
pub(crate) struct RefineParams {
    pub radius_prior_m: f64,
    pub radius_prior_sigma_m: f64,
    pub huber_sigmas: f64,
    pub iterations: usize,
    pub fix_radius: bool,
}

/// Least-squares weight of a residual with noise `sigma`: `1 / sigma^2`, scaled down (Huber)
/// beyond `huber_sigmas` sigmas.
fn huber_weight(residual: f64, sigma: f64, huber_sigmas: f64) -> f64 {
    let normalized = (residual / sigma).abs();
    let huber = if normalized <= huber_sigmas {
        1.0
    } else {
        huber_sigmas / normalized
    };
    huber / (sigma * sigma)
}

/// Weighted robust least squares on the sphere (Gauss-Newton):
/// minimise `sum_i rho_huber((|p_i - c| - r) / sigma(z_i)) + ((r - r_prior) / sigma_r)^2`
/// over centre `c` and radius `r` (or `c` alone with `fix_radius`). `sigma(z)` is the ToF noise
/// scale; the radius prior keeps the problem well posed when only a small cap is visible (the
/// centre then slides along the view ray together with `r`).
pub(crate) fn refine(
    points: &[[f64; 3]],
    noise: &DepthNoiseModel,
    initial: Sphere,
    params: &RefineParams,
) -> Option<Sphere> {
    let mut sphere = initial;
    let prior_weight = 1.0 / (params.radius_prior_sigma_m * params.radius_prior_sigma_m);
    for _ in 0..params.iterations {
        let mut hessian = Matrix4::<f64>::zeros();
        let mut gradient = Vector4::<f64>::zeros();
        for &p in points {
            let d = sub(p, sphere.centre);
            let distance = norm(d);
            if distance < 1e-9 {
                continue;
            }
            let residual = distance - sphere.radius;
            let weight = huber_weight(residual, noise.sigma_m(p[2]), params.huber_sigmas);
            let jacobian = Vector4::new(-d[0] / distance, -d[1] / distance, -d[2] / distance, -1.0);
            hessian += weight * jacobian * jacobian.transpose();
            gradient += weight * residual * jacobian;
        }
        hessian[(3, 3)] += prior_weight;
        gradient[3] += prior_weight * (sphere.radius - params.radius_prior_m);
        if params.fix_radius {
            hessian[(3, 3)] += 1e12;
            gradient[3] = 0.0;
        }
        // Light Levenberg damping keeps the step bounded on degenerate point sets.
        for i in 0..4 {
            hessian[(i, i)] *= 1.0 + 1e-6;
        }
        let step = hessian.cholesky()?.solve(&(-gradient));
        sphere.centre[0] += step[0];
        sphere.centre[1] += step[1];
        sphere.centre[2] += step[2];
        sphere.radius += step[3];
        if !sphere.is_finite() {
            return None;
        }
        if step.norm() < 1e-7 {
            break;
        }
    }
    Some(sphere)
}

/// Smallest half chord used in the along-ray model, in radii: keeps the Jacobian bounded for rays
/// that graze the sphere.
const MIN_HALF_CHORD_RADII: f64 = 0.1;

/// Robust least squares on the sphere with the error where the sensor makes it: along each
/// point's viewing ray (a ToF pixel's or a LiDAR beam's range errs, its direction hardly does).
/// Each point `p` (range `rho = |p|`, direction `u`) predicts the range `t(c, r)` at which its ray
/// enters the sphere; the residual is `(rho - t) / sigma_range`. A ray that misses the sphere is
/// penalised by its miss distance over `lateral_sigma(z)` (the pixel footprint). Huber weights
/// and the Gaussian radius prior as in [`refine`].
///
/// The point-to-sphere distance of [`refine`] treats the noise as isotropic: near the silhouette a
/// range error moves a point along the surface, always outwards from the centre, which pulls the
/// centre towards the camera by about `sigma^2 / r` (5 mm for the ToF camera, 2 cm for a 2 cm
/// LiDAR). The along-ray residual has no such bias.
pub(crate) fn refine_along_rays(
    points: &[[f64; 3]],
    noise: &DepthNoiseModel,
    lateral_sigma_per_m: f64,
    initial: Sphere,
    params: &RefineParams,
) -> Option<Sphere> {
    let mut sphere = initial;
    let centre_distance = norm(initial.centre);
    if centre_distance.is_nan() || centre_distance <= 0.0 {
        return None;
    }
    let direction = initial.centre.map(|v| v / centre_distance);
    let prior_weight = 1.0 / (params.radius_prior_sigma_m * params.radius_prior_sigma_m);
    for _ in 0..params.iterations {
        let mut hessian = Matrix4::<f64>::zeros();
        let mut gradient = Vector4::<f64>::zeros();
        let c = sphere.centre;
        let cc = dot(c, c);
        for &p in points {
            let range = norm(p);
            if range < 1e-9 {
                continue;
            }
            let u = [p[0] / range, p[1] / range, p[2] / range];
            let b = dot(u, c);
            let offset = [c[0] - b * u[0], c[1] - b * u[1], c[2] - b * u[2]];
            let miss_sq = (cc - b * b).max(0.0);
            let discriminant = sphere.radius * sphere.radius - miss_sq;
            let (residual, sigma, jacobian) = if discriminant >= 0.0 {
                // Entry range t = b - sqrt(disc); dt/dc = u - offset / sqrt(disc),
                // dt/dr = -r / sqrt(disc); the residual is rho - t.
                let half_chord = discriminant
                    .sqrt()
                    .max(MIN_HALF_CHORD_RADII * sphere.radius);
                let entry = b - discriminant.sqrt();
                let jacobian = Vector4::new(
                    -(u[0] - offset[0] / half_chord),
                    -(u[1] - offset[1] / half_chord),
                    -(u[2] - offset[2] / half_chord),
                    sphere.radius / half_chord,
                );
                let sigma = noise.sigma_m(p[2]) / u[2].abs().max(0.1);
                (range - entry, sigma, jacobian)
            } else {
                // Miss distance m = |offset| - r; dm/dc = offset / |offset|, dm/dr = -1.
                let miss = miss_sq.sqrt();
                let jacobian =
                    Vector4::new(offset[0] / miss, offset[1] / miss, offset[2] / miss, -1.0);
                (miss - sphere.radius, lateral_sigma_per_m * p[2], jacobian)
            };
            let weight = huber_weight(residual, sigma, params.huber_sigmas);
            hessian += weight * jacobian * jacobian.transpose();
            gradient += weight * residual * jacobian;
        }
        hessian[(3, 3)] += prior_weight;
        gradient[3] += prior_weight * (sphere.radius - params.radius_prior_m);
        // Two unknowns: the centre's distance along its own viewing ray, and the radius.
        let along = Vector4::new(direction[0], direction[1], direction[2], 0.0);
        let radius_axis = Vector4::new(0.0, 0.0, 0.0, 1.0);
        let h_aa = (along.transpose() * hessian * along)[(0, 0)];
        let h_ar = (along.transpose() * hessian * radius_axis)[(0, 0)];
        let h_rr = hessian[(3, 3)] + if params.fix_radius { 1e12 } else { 0.0 };
        let (g_a, g_r) = (
            along.dot(&gradient),
            if params.fix_radius { 0.0 } else { gradient[3] },
        );
        let determinant = h_aa * h_rr - h_ar * h_ar;
        if determinant.is_nan() || determinant <= 0.0 {
            return None;
        }
        let step = (-(h_rr * g_a) + h_ar * g_r) / determinant;
        let radius_step = (-(h_aa * g_r) + h_ar * g_a) / determinant;
        for (centre, along) in sphere.centre.iter_mut().zip(direction) {
            *centre += step * along;
        }
        sphere.radius += radius_step;
        if !sphere.is_finite() {
            return None;
        }
        if step.abs() + radius_step.abs() < 1e-7 {
            break;
        }
    }
    Some(sphere)
}

/// RMS distance of `points` from their least-squares plane (square root of the smallest
/// eigenvalue of their covariance); `None` for fewer than 3 points.
pub(crate) fn plane_rms(points: &[[f64; 3]]) -> Option<f64> {
    if points.len() < 3 {
        return None;
    }
    let n = points.len() as f64;
    let mean = points
        .iter()
        .fold(Vector3::zeros(), |acc: Vector3<f64>, p| {
            acc + Vector3::from(*p)
        })
        / n;
    let covariance = points
        .iter()
        .fold(Matrix3::zeros(), |acc: Matrix3<f64>, p| {
            let d = Vector3::from(*p) - mean;
            acc + d * d.transpose()
        })
        / n;
    let smallest = SymmetricEigen::new(covariance).eigenvalues.min();
    smallest.is_finite().then(|| smallest.max(0.0).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn three_points_on_a_sphere_recover_it() {
        let truth = Sphere {
            centre: [0.1, -0.05, 1.0],
            radius: 0.04,
        };
        let on = |dir: [f64; 3]| {
            let n = norm(dir);
            [
                truth.centre[0] + truth.radius * dir[0] / n,
                truth.centre[1] + truth.radius * dir[1] / n,
                truth.centre[2] + truth.radius * dir[2] / n,
            ]
        };
        let (a, b, c) = (
            on([0.3, 0.1, -1.0]),
            on([-0.4, 0.2, -1.0]),
            on([0.0, -0.5, -1.0]),
        );
        let sphere = sphere_through_three(a, b, c, 0.04, 0.05).expect("sphere");
        for axis in 0..3 {
            assert!(
                (sphere.centre[axis] - truth.centre[axis]).abs() < 1e-9,
                "{sphere:?}"
            );
        }
        // Collinear points have no sphere.
        assert!(sphere_through_three(a, a, c, 0.04, 0.05).is_none());
        // Points spread wider than the maximum radius have none either.
        assert!(
            sphere_through_three(
                [0.0, 0.0, 1.0],
                [0.2, 0.0, 1.0],
                [0.0, 0.2, 1.0],
                0.04,
                0.05
            )
            .is_none()
        );
    }

    #[test]
    fn plane_rms_separates_planes_from_caps() {
        let plane: Vec<[f64; 3]> = (0..100)
            .map(|i| {
                [
                    (i % 10) as f64 * 0.005,
                    (i / 10) as f64 * 0.005,
                    1.0 + (i % 10) as f64 * 0.002,
                ]
            })
            .collect();
        assert!(plane_rms(&plane).expect("enough points") < 1e-9);
        let cap: Vec<[f64; 3]> = (0..100)
            .filter_map(|i| {
                let (x, y) = (
                    (i % 10) as f64 * 0.008 - 0.036,
                    (i / 10) as f64 * 0.008 - 0.036,
                );
                let rho_sq = x * x + y * y;
                (rho_sq < 0.04 * 0.04).then(|| [x, y, 1.0 - (0.04 * 0.04 - rho_sq).sqrt()])
            })
            .collect();
        assert!(plane_rms(&cap).expect("enough points") > 0.005);
        assert!(plane_rms(&cap[..2]).is_none());
    }

    #[test]
    fn refinement_converges_from_a_displaced_start() {
        let truth = Sphere {
            centre: [0.0, 0.0, 1.0],
            radius: 0.042,
        };
        let mut points = Vec::new();
        for i in 0..20 {
            for j in 0..20 {
                let (x, y) = (-0.038 + 0.004 * i as f64, -0.038 + 0.004 * j as f64);
                let rho_sq = x * x + y * y;
                if rho_sq < truth.radius * truth.radius {
                    points.push([x, y, 1.0 - (truth.radius * truth.radius - rho_sq).sqrt()]);
                }
            }
        }
        let start = Sphere {
            centre: [0.01, -0.01, 0.98],
            radius: 0.04,
        };
        let params = RefineParams {
            radius_prior_m: 0.042,
            radius_prior_sigma_m: 0.005,
            huber_sigmas: 1.5,
            iterations: 20,
            fix_radius: false,
        };
        let fitted = refine(&points, &DepthNoiseModel::TL460, start, &params).expect("fit");
        for axis in 0..3 {
            assert!(
                (fitted.centre[axis] - truth.centre[axis]).abs() < 1e-5,
                "{fitted:?}"
            );
        }
        assert!((fitted.radius - truth.radius).abs() < 1e-5);
        assert!(fitted.faces_camera(points[0], 0.0));
    }
}
