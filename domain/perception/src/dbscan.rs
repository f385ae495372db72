//! DBSCAN (Ester et al. 1996) over 3D points, with a uniform-grid spatial index.
//!
//! [dual-arm sec. 3.1.3] clusters each apple's mask points with DBSCAN to separate the fruit
//! surface from occluders, background and flying pixels. A point is a core point when at least
//! `min_points` points (itself included) lie within `eps_m`; clusters are the connected sets of
//! core points plus the border points within `eps_m` of them; all other points are noise.
//!
//! Index: points are bucketed into cubic cells of side `eps_m`; the neighbours of a point lie in
//! its 3x3x3 block of cells. When the occupied bounding box is small (the usual case: one fruit
//! and its surroundings), the cells form a dense x-fastest array filled by counting sort, so the
//! three x-cells of each of the 9 `(y, z)` rows are one contiguous run of points. When outliers
//! spread the box too far, the occupied cells are instead sorted by a packed `(z, y, x)` key and
//! each row is found by binary search. Points are stored in cell order for locality. Building is
//! O(n) (dense) or O(n log n) (sparse); a query is O(9 + k) or O(9 log c + k) for k candidates.

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

/// How the occupied cells are looked up.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
enum GridLayout {
    /// Dense array of `size[0] * size[1] * size[2]` cells starting at cell `origin`.
    Dense { origin: [i32; 3], size: [usize; 3] },
    /// Sorted packed keys with binary search.
    #[default]
    Sparse,
}

/// Reusable DBSCAN state: spatial index, labels and scratch buffers.
#[derive(Debug, Default)]
pub struct Dbscan {
    layout: GridLayout,
    /// Original index of each point in cell order (finite points only).
    order: Vec<u32>,
    /// Points in cell order.
    sorted_points: Vec<[f32; 3]>,
    /// Cell coordinates of each point in cell order.
    sorted_cells: Vec<[i32; 3]>,
    /// Dense: `cell_start[c]..cell_start[c + 1]` are the points of cell `c`.
    /// Sparse: the same for the `c`-th occupied key of `cell_keys`.
    cell_start: Vec<u32>,
    /// Sparse layout: distinct occupied cell keys, ascending.
    cell_keys: Vec<u64>,
    /// Scratch: `(key or dense cell, original index)`.
    keyed: Vec<(u64, u32)>,
    /// Labels in cell order, then in the caller's order.
    sorted_labels: Vec<u32>,
    labels: Vec<u32>,
    cluster_sizes: Vec<u32>,
    neighbours: Vec<u32>,
    stack: Vec<u32>,
}

const KEY_BITS: u32 = 21;
const KEY_OFFSET: i32 = 1 << (KEY_BITS - 1);
const KEY_MAX: i32 = (1 << KEY_BITS) - 2;
/// The dense layout is used while it has at most this many cells per point (plus a constant).
const DENSE_CELLS_PER_POINT: usize = 8;
const DENSE_EXTRA_CELLS: usize = 1 << 15;

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
        let n = self.sorted_points.len();
        self.sorted_labels.clear();
        self.sorted_labels.resize(n, UNVISITED);
        self.cluster_sizes.clear();
        let eps_sq = params.eps_m * params.eps_m;
        for start in 0..n {
            if self.sorted_labels[start] != UNVISITED {
                continue;
            }
            self.query(start, eps_sq);
            if self.neighbours.len() < params.min_points {
                self.sorted_labels[start] = NOISE;
                continue;
            }
            let cluster = self.cluster_sizes.len() as u32;
            self.cluster_sizes.push(0);
            self.sorted_labels[start] = cluster;
            self.stack.clear();
            self.claim_neighbours(cluster);
            while let Some(q) = self.stack.pop() {
                self.query(q as usize, eps_sq);
                if self.neighbours.len() >= params.min_points {
                    self.claim_neighbours(cluster);
                }
            }
        }
        self.labels.clear();
        self.labels.resize(points.len(), NOISE);
        for (&original, &label) in self.order.iter().zip(&self.sorted_labels) {
            self.labels[original as usize] = label;
            if let Some(size) = self.cluster_sizes.get_mut(label as usize) {
                *size += 1;
            }
        }
        Ok(self.cluster_sizes.len())
    }

    /// Per-point labels of the last run, in the caller's order.
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
            let label = &mut self.sorted_labels[q as usize];
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
        let cell_of = |p: &[f32; 3]| {
            [
                (p[0] * inverse).floor() as i32,
                (p[1] * inverse).floor() as i32,
                (p[2] * inverse).floor() as i32,
            ]
        };
        let mut lo = [i32::MAX; 3];
        let mut hi = [i32::MIN; 3];
        let mut finite = 0usize;
        for p in points.iter().filter(|p| is_finite(p)) {
            let cell = cell_of(p);
            for axis in 0..3 {
                lo[axis] = lo[axis].min(cell[axis]);
                hi[axis] = hi[axis].max(cell[axis]);
            }
            finite += 1;
        }
        let size =
            [0, 1, 2].map(|axis| (i64::from(hi[axis]) - i64::from(lo[axis]) + 1).max(0) as usize);
        let cells = size[0]
            .checked_mul(size[1])
            .and_then(|c| c.checked_mul(size[2]));
        let dense_limit = DENSE_CELLS_PER_POINT * finite + DENSE_EXTRA_CELLS;
        self.keyed.clear();
        self.cell_start.clear();
        self.cell_keys.clear();
        match cells {
            Some(cells) if finite > 0 && cells <= dense_limit => {
                self.layout = GridLayout::Dense { origin: lo, size };
                // Counting sort by dense cell index.
                self.cell_start.resize(cells + 1, 0);
                for (i, p) in points.iter().enumerate().filter(|(_, p)| is_finite(p)) {
                    let c = cell_of(p);
                    let index = ((c[2] - lo[2]) as usize * size[1] + (c[1] - lo[1]) as usize)
                        * size[0]
                        + (c[0] - lo[0]) as usize;
                    self.cell_start[index + 1] += 1;
                    self.keyed.push((index as u64, i as u32));
                }
                for c in 0..cells {
                    self.cell_start[c + 1] += self.cell_start[c];
                }
                self.order.clear();
                self.order.resize(finite, 0);
                self.stack.clear();
                self.stack.extend_from_slice(&self.cell_start[..cells]);
                for &(index, original) in &self.keyed {
                    let slot = &mut self.stack[index as usize];
                    self.order[*slot as usize] = original;
                    *slot += 1;
                }
            }
            _ => {
                self.layout = GridLayout::Sparse;
                for (i, p) in points.iter().enumerate().filter(|(_, p)| is_finite(p)) {
                    self.keyed.push((pack(cell_of(p)), i as u32));
                }
                self.keyed.sort_unstable();
                self.order.clear();
                for (position, &(key, original)) in self.keyed.iter().enumerate() {
                    if self.cell_keys.last() != Some(&key) {
                        self.cell_keys.push(key);
                        self.cell_start.push(position as u32);
                    }
                    self.order.push(original);
                }
                self.cell_start.push(self.keyed.len() as u32);
            }
        }
        self.sorted_points.clear();
        self.sorted_cells.clear();
        for &original in &self.order {
            let p = points[original as usize];
            self.sorted_points.push(p);
            self.sorted_cells.push(cell_of(&p));
        }
    }

    /// Fills `self.neighbours` with the (cell-order) points within `sqrt(eps_sq)` of point `i`,
    /// itself included.
    fn query(&mut self, i: usize, eps_sq: f32) {
        self.neighbours.clear();
        let p = self.sorted_points[i];
        let [cx, cy, cz] = self.sorted_cells[i];
        for dz in -1..=1 {
            for dy in -1..=1 {
                let Some(range) = self.row_range(cx, cy + dy, cz + dz) else {
                    continue;
                };
                for (j, q) in self.sorted_points[range.clone()].iter().enumerate() {
                    let d = [q[0] - p[0], q[1] - p[1], q[2] - p[2]];
                    if d[0] * d[0] + d[1] * d[1] + d[2] * d[2] <= eps_sq {
                        self.neighbours.push((range.start + j) as u32);
                    }
                }
            }
        }
    }

    /// Point range (cell order) of cells `x - 1..=x + 1` in row `(y, z)`.
    fn row_range(&self, x: i32, y: i32, z: i32) -> Option<std::ops::Range<usize>> {
        match self.layout {
            GridLayout::Dense { origin, size } => {
                let (ry, rz) = (y - origin[1], z - origin[2]);
                if ry < 0 || rz < 0 || ry as usize >= size[1] || rz as usize >= size[2] {
                    return None;
                }
                let row = (rz as usize * size[1] + ry as usize) * size[0];
                let first = (x - 1 - origin[0]).max(0) as usize;
                let last = ((x + 1 - origin[0]) as usize).min(size[0] - 1);
                let start = self.cell_start[row + first] as usize;
                let end = self.cell_start[row + last + 1] as usize;
                Some(start..end)
            }
            GridLayout::Sparse => {
                let first_key = pack([x - 1, y, z]);
                let last_key = pack([x + 1, y, z]);
                let first = self.cell_keys.partition_point(|&k| k < first_key);
                let last = self.cell_keys.partition_point(|&k| k <= last_key);
                (first < last)
                    .then(|| self.cell_start[first] as usize..self.cell_start[last] as usize)
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
    fn dense_and_sparse_layouts_agree() {
        let mut rng = SmallRng::seed_from_u64(3);
        let spread = Normal::new(0.0_f32, 0.01).expect("valid sigma");
        let mut points: Vec<[f32; 3]> = (0..600)
            .map(|i| {
                let c = if i % 2 == 0 { 0.0 } else { 0.05 };
                [
                    c + spread.sample(&mut rng),
                    spread.sample(&mut rng),
                    1.0 + spread.sample(&mut rng),
                ]
            })
            .collect();
        let params = DbscanParams {
            eps_m: 0.006,
            min_points: 5,
        };
        let mut dbscan = Dbscan::new();
        let clusters = dbscan.run(&points, params).expect("valid");
        assert!(matches!(dbscan.layout, GridLayout::Dense { .. }));
        let dense_labels = dbscan.labels().to_vec();
        // One point 5 km away makes the bounding box too large for the dense layout.
        points.push([5000.0, 0.0, 1.0]);
        assert_eq!(dbscan.run(&points, params), Ok(clusters));
        assert_eq!(dbscan.layout, GridLayout::Sparse);
        assert_eq!(&dbscan.labels()[..600], &dense_labels[..]);
        assert_eq!(dbscan.labels()[600], NOISE);
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
