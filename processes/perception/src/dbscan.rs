//! DBSCAN (Ester et al. 1996) over 3D points, with a uniform-grid spatial index.
//!
//! Zhu et al. 3.1.3 cluster each apple's mask points with DBSCAN to separate the fruit surface
//! from occluders, background and flying pixels. A point is a core point when at least
//! `min_points` points (itself included) lie within `eps_m`; clusters are the connected sets of
//! core points plus the border points within `eps_m` of them; all other points are noise.
//!
//! Index: points are bucketed into cubic cells of side `eps_m`, the cells sorted by a packed key
//! `(z, y, x)`. The neighbours of a point lie in its 3x3x3 block of cells; for each of the 9
//! `(y, z)` rows the three x-cells are consecutive keys, found by one binary search. Building is
//! O(n log n), a query O(9 log c + k) for c occupied cells and k candidates.

use thiserror::Error;

/// Label of a point that belongs to no cluster.
pub const NOISE: u32 = u32::MAX;
const UNVISITED: u32 = u32::MAX - 1;

/// DBSCAN parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DbscanParams {
    /// Neighbourhood radius, metres.
    pub eps_m: f32,
    /// Minimum neighbourhood size of a core point, the point itself included.
    pub min_points: usize,
}

/// Invalid DBSCAN parameters.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum DbscanError {
    /// `eps_m` must be finite and positive.
    #[error("DBSCAN eps_m = {eps_m} must be finite and > 0")]
    InvalidEps { eps_m: f32 },
    /// `min_points` must be at least 1.
    #[error("DBSCAN min_points = {min_points} must be >= 1")]
    InvalidMinPoints { min_points: usize },
}

/// Reusable DBSCAN state: spatial index, labels and scratch buffers.
#[derive(Debug, Default)]
pub struct Dbscan {
    /// `(cell key, point index)` sorted by key.
    sorted: Vec<(u64, u32)>,
    /// Distinct occupied cell keys, ascending.
    cell_keys: Vec<u64>,
    /// `cell_start[c]..cell_start[c + 1]` indexes `sorted` for cell `c`.
    cell_start: Vec<u32>,
    /// Integer cell coordinates of each point (unused for non-finite points).
    cell_of: Vec<[i32; 3]>,
    labels: Vec<u32>,
    cluster_sizes: Vec<u32>,
    neighbours: Vec<u32>,
    stack: Vec<u32>,
}

const KEY_BITS: u32 = 21;
const KEY_OFFSET: i32 = 1 << (KEY_BITS - 1);
const KEY_MAX: i32 = (1 << KEY_BITS) - 2;

fn pack(cell: [i32; 3]) -> u64 {
    let c = |v: i32| (v + KEY_OFFSET).clamp(1, KEY_MAX) as u64;
    (c(cell[2]) << (2 * KEY_BITS)) | (c(cell[1]) << KEY_BITS) | c(cell[0])
}

impl Dbscan {
    pub fn new() -> Self {
        Self::default()
    }

    /// Clusters `points`; returns the number of clusters. Labels are then available from
    /// [`Self::labels`] (cluster id `0..n` or [`NOISE`]). Non-finite points are noise.
    pub fn run(&mut self, points: &[[f32; 3]], params: DbscanParams) -> Result<usize, DbscanError> {
        if !params.eps_m.is_finite() || params.eps_m <= 0.0 {
            return Err(DbscanError::InvalidEps {
                eps_m: params.eps_m,
            });
        }
        if params.min_points == 0 {
            return Err(DbscanError::InvalidMinPoints {
                min_points: params.min_points,
            });
        }
        self.build_index(points, params.eps_m);
        let n = points.len();
        self.labels.clear();
        self.labels.resize(n, UNVISITED);
        self.cluster_sizes.clear();
        let eps_sq = params.eps_m * params.eps_m;
        for start in 0..n {
            if self.labels[start] != UNVISITED {
                continue;
            }
            if !is_finite(&points[start]) {
                self.labels[start] = NOISE;
                continue;
            }
            self.query(points, start, eps_sq);
            if self.neighbours.len() < params.min_points {
                self.labels[start] = NOISE;
                continue;
            }
            let cluster = self.cluster_sizes.len() as u32;
            self.cluster_sizes.push(0);
            self.labels[start] = cluster;
            self.stack.clear();
            self.claim_neighbours(cluster);
            while let Some(q) = self.stack.pop() {
                self.query(points, q as usize, eps_sq);
                if self.neighbours.len() >= params.min_points {
                    self.claim_neighbours(cluster);
                }
            }
        }
        for &label in &self.labels {
            if let Some(size) = self.cluster_sizes.get_mut(label as usize) {
                *size += 1;
            }
        }
        Ok(self.cluster_sizes.len())
    }

    /// Per-point labels of the last run.
    pub fn labels(&self) -> &[u32] {
        &self.labels
    }

    /// Number of points in each cluster of the last run.
    pub fn cluster_sizes(&self) -> &[u32] {
        &self.cluster_sizes
    }

    /// `(cluster id, size)` of the largest cluster of the last run (lowest id on ties).
    pub fn largest_cluster(&self) -> Option<(u32, u32)> {
        let mut best: Option<(u32, u32)> = None;
        for (id, &size) in self.cluster_sizes.iter().enumerate() {
            if best.is_none_or(|(_, best_size)| size > best_size) {
                best = Some((id as u32, size));
            }
        }
        best
    }

    /// Assigns the current neighbour list to `cluster`: unvisited points are queued for
    /// expansion, noise points become border points.
    fn claim_neighbours(&mut self, cluster: u32) {
        for &q in &self.neighbours {
            let label = &mut self.labels[q as usize];
            if *label == UNVISITED {
                *label = cluster;
                self.stack.push(q);
            } else if *label == NOISE {
                *label = cluster;
            }
        }
    }

    fn build_index(&mut self, points: &[[f32; 3]], eps_m: f32) {
        let inverse = 1.0 / eps_m;
        self.sorted.clear();
        self.cell_of.clear();
        for (i, p) in points.iter().enumerate() {
            let cell = [
                (p[0] * inverse).floor() as i32,
                (p[1] * inverse).floor() as i32,
                (p[2] * inverse).floor() as i32,
            ];
            self.cell_of.push(cell);
            if is_finite(p) {
                self.sorted.push((pack(cell), i as u32));
            }
        }
        self.sorted.sort_unstable();
        self.cell_keys.clear();
        self.cell_start.clear();
        for (position, &(key, _)) in self.sorted.iter().enumerate() {
            if self.cell_keys.last() != Some(&key) {
                self.cell_keys.push(key);
                self.cell_start.push(position as u32);
            }
        }
        self.cell_start.push(self.sorted.len() as u32);
    }

    /// Fills `self.neighbours` with the points within `sqrt(eps_sq)` of point `i` (itself included).
    fn query(&mut self, points: &[[f32; 3]], i: usize, eps_sq: f32) {
        self.neighbours.clear();
        let p = points[i];
        let [cx, cy, cz] = self.cell_of[i];
        for dz in -1..=1 {
            for dy in -1..=1 {
                let first = pack([cx - 1, cy + dy, cz + dz]);
                let last = pack([cx + 1, cy + dy, cz + dz]);
                let mut cell = self.cell_keys.partition_point(|&k| k < first);
                while cell < self.cell_keys.len() && self.cell_keys[cell] <= last {
                    let range = self.cell_start[cell] as usize..self.cell_start[cell + 1] as usize;
                    for &(_, j) in &self.sorted[range] {
                        let q = points[j as usize];
                        let d = [q[0] - p[0], q[1] - p[1], q[2] - p[2]];
                        if d[0] * d[0] + d[1] * d[1] + d[2] * d[2] <= eps_sq {
                            self.neighbours.push(j);
                        }
                    }
                    cell += 1;
                }
            }
        }
    }
}

fn is_finite(p: &[f32; 3]) -> bool {
    p.iter().all(|v| v.is_finite())
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::rngs::SmallRng;
    use rand::{Rng, SeedableRng};
    use rand_distr::{Distribution, Normal};

    /// O(n^2) reference: which points are core points.
    fn brute_force_core(points: &[[f32; 3]], params: DbscanParams) -> Vec<bool> {
        let eps_sq = params.eps_m * params.eps_m;
        points
            .iter()
            .map(|p| {
                points
                    .iter()
                    .filter(|q| (0..3).map(|a| (p[a] - q[a]).powi(2)).sum::<f32>() <= eps_sq)
                    .count()
                    >= params.min_points
            })
            .collect()
    }

    #[test]
    fn finds_three_blobs_and_marks_scattered_points_as_noise() {
        let mut rng = SmallRng::seed_from_u64(7);
        let centres = [[0.0_f32, 0.0, 1.0], [0.2, 0.0, 1.0], [0.0, 0.1, 1.5]];
        let spread = Normal::new(0.0_f32, 0.008).expect("valid sigma");
        let mut points = Vec::new();
        let mut truth = Vec::new();
        for (k, c) in centres.iter().enumerate() {
            for _ in 0..300 {
                points.push([
                    c[0] + spread.sample(&mut rng),
                    c[1] + spread.sample(&mut rng),
                    c[2] + spread.sample(&mut rng),
                ]);
                truth.push(k);
            }
        }
        let scattered_start = points.len();
        for _ in 0..40 {
            points.push([
                rng.random_range(-2.0..2.0),
                rng.random_range(-2.0..2.0),
                rng.random_range(3.0..6.0),
            ]);
        }
        points.push([f32::NAN, 0.0, 1.0]);
        let params = DbscanParams {
            eps_m: 0.01,
            min_points: 8,
        };
        let mut dbscan = Dbscan::new();
        let clusters = dbscan.run(&points, params).expect("valid params");
        assert_eq!(clusters, 3);
        let labels = dbscan.labels();
        // Every blob maps to exactly one cluster id, distinct per blob.
        for k in 0..3 {
            let mut ids: Vec<u32> = (0..scattered_start)
                .filter(|&i| truth[i] == k && labels[i] != NOISE)
                .map(|i| labels[i])
                .collect();
            ids.dedup();
            assert_eq!(ids.len(), 1, "blob {k} split into {ids:?}");
        }
        assert!(labels[scattered_start..].iter().all(|&l| l == NOISE));
        let sizes_sum: u32 = dbscan.cluster_sizes().iter().sum();
        let labelled = labels.iter().filter(|&&l| l != NOISE).count() as u32;
        assert_eq!(sizes_sum, labelled);
        assert!(
            labelled >= 850,
            "most blob points clustered, got {labelled}"
        );

        // Core points agree with the brute-force definition, and every core point is labelled.
        let core = brute_force_core(&points, params);
        for (i, &is_core) in core.iter().enumerate() {
            if is_core {
                assert_ne!(labels[i], NOISE, "core point {i} labelled noise");
            }
        }
    }

    #[test]
    fn chain_of_points_is_one_cluster_and_gap_splits_it() {
        // Points every 5 mm along x; a 30 mm gap after the 20th point.
        let mut points: Vec<[f32; 3]> = (0..20).map(|i| [i as f32 * 0.005, 0.0, 1.0]).collect();
        points.extend((0..20).map(|i| [0.125 + i as f32 * 0.005, 0.0, 1.0]));
        let mut dbscan = Dbscan::new();
        let params = DbscanParams {
            eps_m: 0.0075,
            min_points: 3,
        };
        assert_eq!(dbscan.run(&points, params), Ok(2));
        assert_eq!(dbscan.largest_cluster(), Some((0, 20)));
        assert!(dbscan.labels()[..20].iter().all(|&l| l == 0));
        assert!(dbscan.labels()[20..].iter().all(|&l| l == 1));
    }

    #[test]
    fn invalid_parameters_are_errors() {
        let mut dbscan = Dbscan::new();
        let points = [[0.0_f32; 3]];
        assert!(matches!(
            dbscan.run(
                &points,
                DbscanParams {
                    eps_m: f32::NAN,
                    min_points: 3
                }
            ),
            Err(DbscanError::InvalidEps { .. })
        ));
        assert!(matches!(
            dbscan.run(
                &points,
                DbscanParams {
                    eps_m: 0.01,
                    min_points: 0
                }
            ),
            Err(DbscanError::InvalidMinPoints { .. })
        ));
        assert_eq!(
            dbscan.run(
                &[],
                DbscanParams {
                    eps_m: 0.01,
                    min_points: 1
                }
            ),
            Ok(0)
        );
        assert_eq!(dbscan.largest_cluster(), None);
    }
}
