//! Splitting of touching apples: distance-transform peaks as seeds, power-diagram assignment.
//!
//! Two touching discs form one connected region whose distance transform has one peak per disc
//! with a narrow neck between them. Peaks are kept when they are (a) tall enough relative to the
//! region's tallest peak, (b) outside the inscribed circle of every stronger peak and (c) separated
//! from it by a real neck: the distance transform along the segment joining the peaks dips below
//! `saddle_ratio` times the smaller peak. Each region cell then goes to the seed circle
//! `(centre c_k, radius r_k)` minimising the power distance `|p - c_k|^2 - r_k^2`; for two
//! intersecting circles the dividing line is exactly their common chord.

use super::distance_transform::CHAMFER_UNITS_PER_CELL;

/// One apple seed: an inscribed circle in cell coordinates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Seed {
    pub x_cells: f32,
    pub y_cells: f32,
    pub radius_cells: f32,
}

/// Seed selection parameters (see [`super::color_segmentation::ColorSegmentationConfig`]).
#[derive(Debug, Clone, Copy)]
pub(crate) struct SplitParams {
    pub min_seed_radius_cells: f32,
    pub seed_relative_radius: f32,
    pub seed_separation_factor: f32,
    pub saddle_ratio: f32,
    pub max_seeds: usize,
}

/// Finds the seeds of one region. `cells` are the region's row-major cell indices, `distance` the
/// chamfer distance transform of the whole mask. `candidates` is scratch space.
pub(crate) fn find_seeds(
    cells: &[u32],
    distance: &[u16],
    width: usize,
    height: usize,
    params: &SplitParams,
    candidates: &mut Vec<(u16, u32)>,
    seeds: &mut Vec<Seed>,
) {
    seeds.clear();
    candidates.clear();
    let at = |x: isize, y: isize| -> u16 {
        if x < 0 || y < 0 || x >= width as isize || y >= height as isize {
            0
        } else {
            distance
                .get(y as usize * width + x as usize)
                .copied()
                .unwrap_or(0)
        }
    };
    for &index in cells {
        let x = (index as usize % width) as isize;
        let y = (index as usize / width) as isize;
        let d = at(x, y);
        let is_peak = (-1..=1).all(|dy| (-1..=1).all(|dx| at(x + dx, y + dy) <= d));
        if is_peak {
            candidates.push((d, index));
        }
    }
    candidates.sort_unstable_by(|a, b| b.0.cmp(&a.0).then(a.1.cmp(&b.1)));
    let Some(&(tallest, _)) = candidates.first() else {
        return;
    };
    let min_units = (params.min_seed_radius_cells * CHAMFER_UNITS_PER_CELL)
        .max(params.seed_relative_radius * tallest as f32);
    for &(d, index) in candidates.iter() {
        if (d as f32) < min_units || seeds.len() >= params.max_seeds {
            break;
        }
        let candidate = Seed {
            x_cells: (index as usize % width) as f32,
            y_cells: (index as usize / width) as f32,
            radius_cells: d as f32 / CHAMFER_UNITS_PER_CELL,
        };
        let separate = seeds.iter().all(|seed| {
            let dx = candidate.x_cells - seed.x_cells;
            let dy = candidate.y_cells - seed.y_cells;
            let gap = (dx * dx + dy * dy).sqrt();
            if gap <= params.seed_separation_factor * seed.radius_cells.max(candidate.radius_cells)
            {
                return false;
            }
            let neck = min_distance_along(seed, &candidate, &at);
            neck < params.saddle_ratio * seed.radius_cells.min(candidate.radius_cells)
        });
        if separate {
            seeds.push(candidate);
        }
    }
}

/// Minimum distance-transform value (cells) sampled every half cell on the segment `a`-`b`.
fn min_distance_along(a: &Seed, b: &Seed, at: &impl Fn(isize, isize) -> u16) -> f32 {
    let dx = b.x_cells - a.x_cells;
    let dy = b.y_cells - a.y_cells;
    let steps = ((dx * dx + dy * dy).sqrt() * 2.0).ceil().max(1.0) as usize;
    let mut minimum = u16::MAX;
    for step in 0..=steps {
        let t = step as f32 / steps as f32;
        let x = (a.x_cells + t * dx).round() as isize;
        let y = (a.y_cells + t * dy).round() as isize;
        minimum = minimum.min(at(x, y));
    }
    minimum as f32 / CHAMFER_UNITS_PER_CELL
}

/// Index of the seed whose circle has the smallest power distance to cell `(x, y)`.
pub(crate) fn nearest_seed(x_cells: f32, y_cells: f32, seeds: &[Seed]) -> usize {
    let mut best = 0;
    let mut best_power = f32::INFINITY;
    for (k, seed) in seeds.iter().enumerate() {
        let dx = x_cells - seed.x_cells;
        let dy = y_cells - seed.y_cells;
        let power = dx * dx + dy * dy - seed.radius_cells * seed.radius_cells;
        if power < best_power {
            best_power = power;
            best = k;
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::super::distance_transform::chamfer_distance;
    use super::*;

    const PARAMS: SplitParams = SplitParams {
        min_seed_radius_cells: 2.0,
        seed_relative_radius: 0.35,
        seed_separation_factor: 0.9,
        saddle_ratio: 0.9,
        max_seeds: 12,
    };

    fn discs(width: usize, height: usize, discs: &[(f32, f32, f32)]) -> Vec<u8> {
        (0..width * height)
            .map(|i| {
                let (x, y) = ((i % width) as f32, (i / width) as f32);
                u8::from(
                    discs
                        .iter()
                        .any(|&(cx, cy, r)| (x - cx) * (x - cx) + (y - cy) * (y - cy) <= r * r),
                )
            })
            .collect()
    }

    fn seeds_of(mask: &[u8], width: usize, height: usize) -> Vec<Seed> {
        let mut distance = Vec::new();
        chamfer_distance(mask, width, height, &mut distance);
        let cells: Vec<u32> = (0..mask.len() as u32)
            .filter(|&i| mask[i as usize] != 0)
            .collect();
        let (mut candidates, mut seeds) = (Vec::new(), Vec::new());
        find_seeds(
            &cells,
            &distance,
            width,
            height,
            &PARAMS,
            &mut candidates,
            &mut seeds,
        );
        seeds
    }

    #[test]
    fn single_disc_gives_one_seed() {
        let mask = discs(60, 60, &[(30.0, 30.0, 12.0)]);
        let seeds = seeds_of(&mask, 60, 60);
        assert_eq!(seeds.len(), 1, "{seeds:?}");
        assert!((seeds[0].x_cells - 30.0).abs() <= 1.0);
        assert!((seeds[0].y_cells - 30.0).abs() <= 1.0);
    }

    #[test]
    fn touching_and_overlapping_discs_give_two_seeds() {
        for gap in [24.0, 20.0, 17.0] {
            let mask = discs(80, 50, &[(25.0, 25.0, 12.0), (25.0 + gap, 25.0, 12.0)]);
            let seeds = seeds_of(&mask, 80, 50);
            assert_eq!(seeds.len(), 2, "centre distance {gap}: {seeds:?}");
            let left = nearest_seed(20.0, 25.0, &seeds);
            let right = nearest_seed(30.0 + gap, 25.0, &seeds);
            assert_ne!(left, right);
        }
    }

    #[test]
    fn ellipse_is_not_split() {
        let (w, h) = (80, 50);
        let mask: Vec<u8> = (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f32 - 40.0, (i / w) as f32 - 25.0);
                u8::from((x / 16.0).powi(2) + (y / 12.0).powi(2) <= 1.0)
            })
            .collect();
        assert_eq!(seeds_of(&mask, w, h).len(), 1);
    }
}
