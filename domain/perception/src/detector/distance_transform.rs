//! Chamfer (3-4) distance transform of a binary cell mask.
//!
//! Each set cell receives its distance to the nearest unset cell in thirds of a cell
//! (axis step 3, diagonal step 4, within 8 % of the Euclidean distance). Cells outside the image
//! count as unset, so a cell on the border has distance 3.

/// Chamfer units per cell.
pub(crate) const CHAMFER_UNITS_PER_CELL: f32 = 3.0;

/// Computes the 3-4 chamfer distance transform of `mask` into `distance`.
pub(crate) fn chamfer_distance(mask: &[u8], width: usize, height: usize, distance: &mut Vec<u16>) {
    let n = width * height;
    distance.clear();
    distance.resize(n, 0);
    if n == 0 || mask.len() < n {
        return;
    }
    let at = |d: &[u16], x: isize, y: isize| -> u16 {
        if x < 0 || y < 0 || x >= width as isize || y >= height as isize {
            0
        } else {
            d[y as usize * width + x as usize]
        }
    };
    for y in 0..height {
        for x in 0..width {
            let index = y * width + x;
            if mask[index] == 0 {
                continue;
            }
            let (xi, yi) = (x as isize, y as isize);
            let best = (at(distance, xi - 1, yi).saturating_add(3))
                .min(at(distance, xi, yi - 1).saturating_add(3))
                .min(at(distance, xi - 1, yi - 1).saturating_add(4))
                .min(at(distance, xi + 1, yi - 1).saturating_add(4));
            distance[index] = best;
        }
    }
    for y in (0..height).rev() {
        for x in (0..width).rev() {
            let index = y * width + x;
            if mask[index] == 0 {
                continue;
            }
            let (xi, yi) = (x as isize, y as isize);
            let best = distance[index]
                .min(at(distance, xi + 1, yi).saturating_add(3))
                .min(at(distance, xi, yi + 1).saturating_add(3))
                .min(at(distance, xi + 1, yi + 1).saturating_add(4))
                .min(at(distance, xi - 1, yi + 1).saturating_add(4));
            distance[index] = best;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn disc_centre_distance_matches_radius() {
        let (w, h) = (41, 41);
        let radius = 15.0_f32;
        let mask: Vec<u8> = (0..w * h)
            .map(|i| {
                let dx = (i % w) as f32 - 20.0;
                let dy = (i / w) as f32 - 20.0;
                u8::from(dx * dx + dy * dy <= radius * radius)
            })
            .collect();
        let mut distance = Vec::new();
        chamfer_distance(&mask, w, h, &mut distance);
        let centre = distance[20 * w + 20] as f32 / CHAMFER_UNITS_PER_CELL;
        assert!(
            (centre - radius).abs() <= 1.5,
            "centre distance {centre} cells for radius {radius}"
        );
        assert_eq!(distance[0], 0);
        // The maximum is at the centre.
        let max = distance.iter().copied().max().unwrap_or(0);
        assert_eq!(max, distance[20 * w + 20]);
    }
}
