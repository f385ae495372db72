//! The non-repetitive rosette scan of a Risley-prism LiDAR (Livox Mid-40/70 family).
//!
//! Two wedge prisms rotating at angular speeds `w1`, `w2` of opposite sign each deflect the beam
//! by half the field of view; the deflection is the sum of two phasors,
//! `d(t) = (R / 2) (e^{i w1 t} + e^{i w2 t})` with `R` the half cone angle, so `|d| <= R` and the
//! beam traces rosette petals through the centre. With an irrational `w1 / w2` the petals never
//! repeat: each integration window adds new directions and the covered share of the field of
//! view grows with integration time ([`coverage_fraction`] measures it).
//!
//! A return's direction in the LiDAR frame (x forward, y left, z up) is
//! `(cos |d|, sin |d| d_y / |d|, sin |d| d_z / |d|)`.

use harvest_hw::lidar::LidarSpec;

/// The scan directions of one LiDAR over time.
#[derive(Debug, Clone)]
pub struct RosetteScan {
    omega_rad_per_s: [f64; 2],
    half_fov_rad: f64,
    point_period_s: f64,
    next_index: u64,
}

impl RosetteScan {
    /// A scan starting at time zero.
    pub fn new(spec: &LidarSpec) -> Self {
        Self::starting_at(spec, 0)
    }

    /// A scan whose next return is number `start_index` (time `start_index / point_rate`).
    pub fn starting_at(spec: &LidarSpec, start_index: u64) -> Self {
        Self {
            omega_rad_per_s: spec.prism_rev_per_s.map(|rev| std::f64::consts::TAU * rev),
            half_fov_rad: spec.half_fov_rad(),
            point_period_s: 1.0 / spec.point_rate_hz,
            next_index: start_index,
        }
    }

    /// Index of the next return.
    pub fn next_index(&self) -> u64 {
        self.next_index
    }

    /// Time of the next return since the scan's zero, seconds.
    pub fn time_s(&self) -> f64 {
        self.next_index as f64 * self.point_period_s
    }

    /// Beam deflection from the boresight at time `t_s`: `(towards +y, towards +z)`, radians.
    pub fn deflection_rad(&self, t_s: f64) -> [f64; 2] {
        let half = self.half_fov_rad / 2.0;
        let [w1, w2] = self.omega_rad_per_s;
        let (s1, c1) = (w1 * t_s).sin_cos();
        let (s2, c2) = (w2 * t_s).sin_cos();
        [half * (c1 + c2), half * (s1 + s2)]
    }

    /// Unit beam direction in the LiDAR frame at time `t_s`.
    pub fn direction_at(&self, t_s: f64) -> [f64; 3] {
        direction_from_deflection(self.deflection_rad(t_s))
    }

    /// Deflection of the next return (see [`Self::deflection_rad`]); advances the scan by one.
    pub fn next_deflection_rad(&mut self) -> [f64; 2] {
        let t_s = self.next_index as f64 * self.point_period_s;
        self.next_index += 1;
        self.deflection_rad(t_s)
    }

    /// Appends the directions of the next `count` returns to `out` and advances the scan.
    pub fn next_directions(&mut self, count: usize, out: &mut Vec<[f64; 3]>) {
        out.reserve(count);
        for _ in 0..count {
            let t_s = self.next_index as f64 * self.point_period_s;
            out.push(self.direction_at(t_s));
            self.next_index += 1;
        }
    }
}

/// Unit direction (LiDAR frame) of a beam deflected by `[towards +y, towards +z]` radians.
pub fn direction_from_deflection(deflection_rad: [f64; 2]) -> [f64; 3] {
    let [dy, dz] = deflection_rad;
    let angle = (dy * dy + dz * dz).sqrt();
    if angle < 1e-12 {
        return [1.0, 0.0, 0.0];
    }
    let (sin, cos) = angle.sin_cos();
    [cos, sin * dy / angle, sin * dz / angle]
}

/// Deflection `[towards +y, towards +z]` (radians) of a LiDAR-frame direction; inverse of
/// [`direction_from_deflection`] for directions within 90 degrees of the boresight.
pub fn deflection_of(direction: [f64; 3]) -> [f64; 2] {
    let lateral = (direction[1] * direction[1] + direction[2] * direction[2]).sqrt();
    if lateral < 1e-15 {
        return [0.0, 0.0];
    }
    let angle = lateral.atan2(direction[0]);
    [
        angle * direction[1] / lateral,
        angle * direction[2] / lateral,
    ]
}

/// Share of the circular field of view (half angle `half_fov_rad`) hit by at least one of
/// `directions`, on a grid of square cells of `cell_deg` in deflection angle. Allocates the grid.
pub fn coverage_fraction(directions: &[[f64; 3]], half_fov_rad: f64, cell_deg: f64) -> f64 {
    let cell_rad = cell_deg.to_radians();
    let cells = (2.0 * half_fov_rad / cell_rad).ceil() as usize;
    if cells == 0 {
        return 0.0;
    }
    let index = |angle: f64| ((angle + half_fov_rad) / cell_rad).floor();
    let mut hit = vec![false; cells * cells];
    for direction in directions {
        let [dy, dz] = deflection_of(*direction);
        let (i, j) = (index(dy), index(dz));
        if i >= 0.0 && j >= 0.0 && (i as usize) < cells && (j as usize) < cells {
            hit[j as usize * cells + i as usize] = true;
        }
    }
    let (mut inside, mut covered) = (0usize, 0usize);
    for j in 0..cells {
        for i in 0..cells {
            let centre = |k: usize| (k as f64 + 0.5) * cell_rad - half_fov_rad;
            if centre(i).hypot(centre(j)) <= half_fov_rad {
                inside += 1;
                covered += usize::from(hit[j * cells + i]);
            }
        }
    }
    if inside == 0 {
        0.0
    } else {
        covered as f64 / inside as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn directions(spec: &LidarSpec, duration_s: f64) -> Vec<[f64; 3]> {
        let mut scan = RosetteScan::new(spec);
        let mut out = Vec::new();
        scan.next_directions((duration_s * spec.point_rate_hz) as usize, &mut out);
        out
    }

    #[test]
    fn every_direction_is_a_unit_vector_inside_the_circular_fov() {
        let spec = LidarSpec::mid70();
        let half = spec.half_fov_rad();
        for direction in directions(&spec, 0.2) {
            let norm = direction.iter().map(|d| d * d).sum::<f64>().sqrt();
            assert!((norm - 1.0).abs() < 1e-12);
            let off_axis = direction[0].clamp(-1.0, 1.0).acos();
            assert!(off_axis <= half + 1e-9, "{off_axis} rad off the boresight");
        }
    }

    #[test]
    fn coverage_grows_with_integration_time() {
        let spec = LidarSpec::mid70();
        let half = spec.half_fov_rad();
        let cloud = directions(&spec, 2.0);
        let rate = spec.point_rate_hz;
        let coverage =
            |seconds: f64| coverage_fraction(&cloud[..(seconds * rate) as usize], half, 0.25);
        let series: Vec<f64> = [0.1, 0.2, 0.5, 1.0, 2.0].map(coverage).to_vec();
        for pair in series.windows(2) {
            assert!(
                pair[1] > pair[0] + 0.02,
                "coverage does not grow: {series:?}"
            );
        }
        // A repetitive scan would stop growing after its period; the rosette keeps filling.
        assert!(series[0] < 0.5, "{series:?}");
        assert!(series[4] > 0.85, "{series:?}");
    }

    #[test]
    fn the_pattern_does_not_repeat_and_rate_is_the_specs() {
        let spec = LidarSpec::mid70();
        let mut scan = RosetteScan::new(&spec);
        let mut first = Vec::new();
        scan.next_directions(10_000, &mut first);
        assert_eq!(scan.next_index(), 10_000);
        assert!((scan.time_s() - 0.1).abs() < 1e-12);
        let mut later = Vec::new();
        scan.next_directions(10_000, &mut later);
        let same = first
            .iter()
            .zip(&later)
            .filter(|(a, b)| (0..3).all(|k| (a[k] - b[k]).abs() < 1e-6))
            .count();
        assert_eq!(same, 0);
    }

    #[test]
    fn deflection_round_trips_through_direction() {
        for deflection in [[0.1, -0.2], [0.0, 0.3], [-0.5, 0.05]] {
            let back = deflection_of(direction_from_deflection(deflection));
            assert!((back[0] - deflection[0]).abs() < 1e-12);
            assert!((back[1] - deflection[1]).abs() < 1e-12);
        }
    }
}
