//! Shared first stage of the clustering-based estimators: subsampling of the mask points,
//! a depth-adaptive DBSCAN radius, and DBSCAN itself.
//!
//! The DBSCAN radius must bridge the spacing of neighbouring depth samples on the fruit
//! (`z / f_depth` per pixel) and their depth noise, but stay below the depth gap to leaves and
//! background: `eps = max(eps_min_m, eps_pixel_pitches * pitch + eps_noise_sigmas * sigma(z))`
//! with `z` the median depth of the mask points and `pitch = z / f_depth * sqrt(stride)` the
//! sample spacing after keeping every `stride`-th point (at most `max_points` remain).

use serde::{Deserialize, Serialize};
use tracing::warn;

use super::{EstimatorConfigError, EstimatorContext, check_range};
use crate::dbscan::{Dbscan, DbscanParams};

/// DBSCAN settings shared by the clustering estimators.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ClusteringConfig {
    /// Lower bound of the DBSCAN radius, metres.
    pub eps_min_m: f64,
    /// Depth-sample spacings included in the radius.
    pub eps_pixel_pitches: f64,
    /// Depth-noise sigmas included in the radius.
    pub eps_noise_sigmas: f64,
    /// DBSCAN core-point neighbourhood size (point included).
    pub min_points: usize,
    /// Mask points beyond this count are subsampled with a uniform stride (bounds the cost).
    pub max_points: usize,
}

impl Default for ClusteringConfig {
    fn default() -> Self {
        Self {
            eps_min_m: 0.008,
            eps_pixel_pitches: 3.0,
            eps_noise_sigmas: 1.0,
            min_points: 6,
            max_points: 600,
        }
    }
}

impl ClusteringConfig {
    pub fn validate(&self) -> Result<(), EstimatorConfigError> {
        check_range("clustering.eps_min_m", self.eps_min_m, 1e-4, 1.0)?;
        check_range(
            "clustering.eps_pixel_pitches",
            self.eps_pixel_pitches,
            0.0,
            100.0,
        )?;
        check_range(
            "clustering.eps_noise_sigmas",
            self.eps_noise_sigmas,
            0.0,
            100.0,
        )?;
        check_range("clustering.min_points", self.min_points as f64, 1.0, 1e6)?;
        check_range("clustering.max_points", self.max_points as f64, 16.0, 1e8)
    }
}

/// Subsampled points with their DBSCAN labels.
#[derive(Debug)]
pub(crate) struct PointClustering {
    config: ClusteringConfig,
    context: EstimatorContext,
    dbscan: Dbscan,
    sampled: Vec<[f32; 3]>,
    depth_scratch: Vec<f32>,
}

impl PointClustering {
    pub(crate) fn new(config: ClusteringConfig, context: EstimatorContext) -> Self {
        Self {
            config,
            context,
            dbscan: Dbscan::new(),
            sampled: Vec::new(),
            depth_scratch: Vec::new(),
        }
    }

    /// Subsamples and clusters `points`; returns the number of clusters.
    pub(crate) fn run(&mut self, points: &[[f32; 3]]) -> usize {
        self.sampled.clear();
        let stride = points.len().div_ceil(self.config.max_points).max(1);
        self.sampled.extend(
            points
                .iter()
                .step_by(stride)
                .filter(|p| p.iter().all(|v| v.is_finite()) && p[2] > 0.0),
        );
        if self.sampled.is_empty() {
            return 0;
        }
        self.depth_scratch.clear();
        self.depth_scratch.extend(self.sampled.iter().map(|p| p[2]));
        let middle = self.depth_scratch.len() / 2;
        let (_, median, _) = self
            .depth_scratch
            .select_nth_unstable_by(middle, f32::total_cmp);
        let z = f64::from(*median);
        // Subsampling by `stride` widens the sample spacing by about sqrt(stride).
        let pitch_m = z / self.context.depth_focal_px * (stride as f64).sqrt();
        let eps_m = (self.config.eps_pixel_pitches * pitch_m
            + self.config.eps_noise_sigmas * self.context.noise.sigma_m(z))
        .max(self.config.eps_min_m);
        let params = DbscanParams {
            eps_m: eps_m as f32,
            min_points: self.config.min_points,
        };
        match self.dbscan.run(&self.sampled, params) {
            Ok(clusters) => clusters,
            Err(error) => {
                warn!(%error, "DBSCAN rejected its parameters");
                0
            }
        }
    }

    /// Points after subsampling (the ones the labels refer to).
    pub(crate) fn points(&self) -> &[[f32; 3]] {
        &self.sampled
    }

    pub(crate) fn labels(&self) -> &[u32] {
        self.dbscan.labels()
    }

    pub(crate) fn largest_cluster(&self) -> Option<(u32, u32)> {
        self.dbscan.largest_cluster()
    }
}
