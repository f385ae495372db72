//! Over-exposed (clipped, colourless) regions of the colour image and what they are.
//!
//! Direct sunlight blows an apple out to white (the exposure condition of [dual-arm Table 3]).
//! Chromaticity then carries no information, so such cells are neither apple nor background to
//! [`super::color_segmentation`]. Each 8-connected region of them (a *blob*) is sorted here:
//! - **Highlight**: the blob's outer ring is mostly apple-coloured (a specular highlight inside a
//!   red fruit, or a blown-out centre with a red rim). The whole blob joins the apple mask, so a
//!   large highlight does not leave a hole that would split the fruit.
//! - **Candidate**: the blob is disc-shaped and apple-sized but not ringed by red (the whole fruit
//!   is blown out). It becomes a separate detection that the pipeline keeps only when the
//!   registered depth confirms a solid, apple-sized object there
//!   ([`super::DetectionSource::SaturatedBlob`]). White sky has no depth return and is refused.
//! - Anything else (thin, huge, irregular: sky between leaves, bright wood) stays unknown; an
//!   apple region may still absorb a few cells of it.
//!
//! Shape test: the inscribed radius `r_in` (chamfer distance transform) and the fill ratio
//! `area / (pi r_in^2)`, which is about 1 for a disc and grows for elongated or ragged regions.

use super::components::Components;
use super::distance_transform::{CHAMFER_UNITS_PER_CELL, chamfer_distance};

/// Cell classes shared with the colour segmentation.
pub(crate) mod class {
    pub const BACKGROUND: u8 = 0;
    pub const APPLE: u8 = 1;
    /// Over-exposed without usable colour.
    pub const UNKNOWN: u8 = 2;
}

/// Blob sorting parameters, cells of the segmentation grid.
#[derive(Debug, Clone, Copy)]
pub(crate) struct BlobParams {
    /// Smallest candidate area.
    pub min_area_cells: u32,
    /// Smallest inscribed radius of a candidate.
    pub min_radius_cells: f32,
    /// Largest inscribed radius of a candidate (the nearest, largest apple).
    pub max_radius_cells: f32,
    /// Largest fill ratio `area / (pi r_in^2)` of a candidate.
    pub max_fill_ratio: f32,
    /// A blob whose outer ring holds at least this fraction of apple cells is a highlight.
    pub highlight_ring_fraction: f32,
}

/// Counts of one frame's blob sorting.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(crate) struct BlobCounts {
    pub highlights: u32,
    pub candidates: u32,
}

/// Scratch buffers of the blob sorting.
#[derive(Debug, Default)]
pub(crate) struct SaturatedBlobs {
    unknown: Vec<u8>,
    components: Components,
    distance: Vec<u16>,
}

impl SaturatedBlobs {
    /// Sorts the blobs of `class` (row-major `width x height` grid). Highlights are painted into
    /// `apple_mask`; candidates are painted into `candidates` (resized to the grid, 1 = candidate)
    /// and reclassified as background in `class`, so no apple region absorbs them.
    pub(crate) fn sort(
        &mut self,
        class: &mut [u8],
        apple_mask: &mut [u8],
        candidates: &mut Vec<u8>,
        width: usize,
        height: usize,
        params: &BlobParams,
    ) -> BlobCounts {
        let n = width * height;
        candidates.clear();
        candidates.resize(n, 0);
        let mut counts = BlobCounts::default();
        if class.len() < n || apple_mask.len() < n || !class.contains(&class::UNKNOWN) {
            return counts;
        }
        self.unknown.clear();
        self.unknown
            .extend(class.iter().map(|&c| u8::from(c == class::UNKNOWN)));
        self.components.label(&self.unknown, width, height);
        chamfer_distance(&self.unknown, width, height, &mut self.distance);
        for blob in 0..self.components.count() {
            let cells = self.components.cells(blob);
            let (mut ring, mut ring_apple) = (0_u32, 0_u32);
            let mut peak = 0_u16;
            for &index in cells {
                let index = index as usize;
                peak = peak.max(self.distance[index]);
                let (x, y) = (index % width, index / width);
                for ny in y.saturating_sub(1)..=(y + 1).min(height - 1) {
                    for nx in x.saturating_sub(1)..=(x + 1).min(width - 1) {
                        let neighbour = ny * width + nx;
                        if self.unknown[neighbour] == 0 {
                            ring += 1;
                            ring_apple += u32::from(class[neighbour] == class::APPLE);
                        }
                    }
                }
            }
            let ringed =
                ring > 0 && ring_apple as f32 >= params.highlight_ring_fraction * ring as f32;
            if ringed {
                counts.highlights += 1;
                for &index in cells {
                    apple_mask[index as usize] = 1;
                }
                continue;
            }
            let radius = f32::from(peak) / CHAMFER_UNITS_PER_CELL;
            let area = cells.len() as f32;
            let fill = area / (std::f32::consts::PI * radius * radius).max(1.0);
            let candidate = cells.len() as u32 >= params.min_area_cells
                && radius >= params.min_radius_cells
                && radius <= params.max_radius_cells
                && fill <= params.max_fill_ratio;
            if candidate {
                counts.candidates += 1;
                for &index in cells {
                    let index = index as usize;
                    candidates[index] = 1;
                    class[index] = class::BACKGROUND;
                }
            }
        }
        counts
    }
}

#[cfg(test)]
mod tests {
    use super::class::{APPLE, BACKGROUND, UNKNOWN};
    use super::*;

    const W: usize = 60;
    const H: usize = 40;

    fn params() -> BlobParams {
        BlobParams {
            min_area_cells: 10,
            min_radius_cells: 2.0,
            max_radius_cells: 12.0,
            max_fill_ratio: 2.0,
            highlight_ring_fraction: 0.5,
        }
    }

    fn disc(class: &mut [u8], cx: f32, cy: f32, r: f32, value: u8) {
        for y in 0..H {
            for x in 0..W {
                if (x as f32 - cx).powi(2) + (y as f32 - cy).powi(2) <= r * r {
                    class[y * W + x] = value;
                }
            }
        }
    }

    #[test]
    fn ringed_blob_is_a_highlight_and_bare_disc_is_a_candidate() {
        let mut class = vec![BACKGROUND; W * H];
        // Red fruit with a large blown-out centre.
        disc(&mut class, 15.0, 20.0, 10.0, APPLE);
        disc(&mut class, 15.0, 20.0, 6.0, UNKNOWN);
        // A fully blown-out fruit on leaves.
        disc(&mut class, 45.0, 20.0, 6.0, UNKNOWN);
        // A thin clipped streak (bright wood): neither.
        for x in 30..58 {
            class[2 * W + x] = UNKNOWN;
        }
        let mut mask: Vec<u8> = class.iter().map(|&c| u8::from(c == APPLE)).collect();
        let mut candidates = Vec::new();
        let counts =
            SaturatedBlobs::default().sort(&mut class, &mut mask, &mut candidates, W, H, &params());
        assert_eq!(
            counts,
            BlobCounts {
                highlights: 1,
                candidates: 1
            }
        );
        assert_eq!(mask[20 * W + 15], 1, "highlight joins the fruit");
        assert_eq!(candidates[20 * W + 15], 0);
        assert_eq!(candidates[20 * W + 45], 1);
        assert_eq!(mask[20 * W + 45], 0);
        assert_eq!(class[20 * W + 45], BACKGROUND);
        assert_eq!(class[2 * W + 40], UNKNOWN);
        assert_eq!(candidates[2 * W + 40], 0);
    }

    #[test]
    fn huge_white_area_is_not_a_candidate() {
        let mut class = vec![UNKNOWN; W * H];
        let mut mask = vec![0; W * H];
        let mut candidates = Vec::new();
        let counts =
            SaturatedBlobs::default().sort(&mut class, &mut mask, &mut candidates, W, H, &params());
        assert_eq!(counts, BlobCounts::default());
        assert!(candidates.iter().all(|&c| c == 0));
    }
}
