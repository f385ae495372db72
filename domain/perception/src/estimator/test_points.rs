//! Synthetic ToF samples of the visible cap of a sphere, for the estimator tests.

use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};

use super::EstimatorContext;
use crate::noise_model::DepthNoiseModel;

/// Depth camera focal length used by the samplers (TL460 depth camera, 62 deg over 640 px).
pub(crate) const DEPTH_FOCAL_PX: f64 = 532.5;

pub(crate) fn context() -> EstimatorContext {
    EstimatorContext {
        noise: DepthNoiseModel::TL460,
        depth_focal_px: DEPTH_FOCAL_PX,
    }
}

/// A horizontal leaf in front of the fruit, covering an image band.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Occluder {
    /// Half-height of the band, in fruit radii (as seen in the image).
    pub half_width_radii: f64,
    /// Band centre offset from the fruit centre, in fruit radii.
    pub offset_radii: f64,
    /// Gap between the fruit front and the leaf, metres.
    pub gap_m: f64,
    /// Fraction of the leaf pixels that leak into the mask.
    pub in_mask_fraction: f64,
}

#[derive(Debug, Clone, Copy)]
pub(crate) struct CapScene {
    pub centre_m: [f64; 3],
    pub radius_m: f64,
    /// Multiplier of the TL460 noise sigma.
    pub noise_scale: f64,
    pub occluder: Option<Occluder>,
    /// Fraction of silhouette-edge samples replaced by mixed fruit/background depths.
    pub flying_fraction: f64,
}

impl Default for CapScene {
    fn default() -> Self {
        Self {
            centre_m: [0.0, 0.0, 1.0],
            radius_m: 0.04,
            noise_scale: 1.0,
            occluder: None,
            flying_fraction: 0.0,
        }
    }
}

pub(crate) struct Cap {
    pub points: Vec<[f32; 3]>,
    /// Ray through the projected sphere centre (unit z).
    pub centre_ray: [f64; 3],
}

/// Casts one ray per depth pixel over the fruit's image disc and returns the noisy hits.
pub(crate) fn sample_cap(scene: &CapScene, seed: u64) -> Cap {
    let mut rng = SmallRng::seed_from_u64(seed);
    let standard = Normal::new(0.0, 1.0).expect("unit normal");
    let [cx, cy, cz] = scene.centre_m;
    let r = scene.radius_m;
    let f = DEPTH_FOCAL_PX;
    let (u0, v0) = (f * cx / cz, f * cy / cz);
    let half = (f * r / (cz - r)).ceil() as i64 + 2;
    let noise = DepthNoiseModel::TL460;
    let mut points = Vec::new();
    for dv in -half..=half {
        for du in -half..=half {
            let (u, v) = (u0.round() + du as f64, v0.round() + dv as f64);
            let d = [u / f, v / f, 1.0];
            let dd = d[0] * d[0] + d[1] * d[1] + 1.0;
            let dc = d[0] * cx + d[1] * cy + d[2] * cz;
            let cc = cx * cx + cy * cy + cz * cz;
            let discriminant = dc * dc - dd * (cc - r * r);
            if discriminant < 0.0 {
                continue;
            }
            let mut z = (dc - discriminant.sqrt()) / dd;
            if let Some(occ) = scene.occluder {
                let band_centre = v0 + occ.offset_radii * f * r / cz;
                if (v - band_centre).abs() <= occ.half_width_radii * f * r / cz {
                    if rng.random::<f64>() >= occ.in_mask_fraction {
                        continue;
                    }
                    z = cz - r - occ.gap_m;
                }
            }
            // Grazing samples near the silhouette mix with the background 0.3-0.8 m behind.
            let grazing = discriminant.sqrt() / (dd.sqrt() * r) < 0.3;
            if grazing && rng.random::<f64>() < scene.flying_fraction {
                z += rng.random_range(0.05..0.8);
            }
            z += scene.noise_scale * noise.sigma_m(z) * standard.sample(&mut rng);
            points.push([(d[0] * z) as f32, (d[1] * z) as f32, z as f32]);
        }
    }
    Cap {
        points,
        centre_ray: [cx / cz, cy / cz, 1.0],
    }
}

pub(crate) fn error_m(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}
