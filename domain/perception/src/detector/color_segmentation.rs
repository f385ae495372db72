//! Classical apple detector: chromaticity segmentation on a downscaled image, morphological
//! clean-up, connected components and splitting of touching apples.
//!
//! The paper's detector is learned ([dual-arm sec. 3.1.1]); this is the fallback that needs no
//! model. Pipeline, on cells of `downscale x downscale` colour pixels:
//! 1. Mean colour of each cell, and whether most of its pixels are clipped (over-exposed).
//! 2. Classification in normalized chromaticity `r = R/(R+G+B)`, `g = G/(R+G+B)`, which does not
//!    change when the illumination scales all channels: a cell is apple when the red excess
//!    `r - g` exceeds a threshold. Near clipping the colour washes out towards white, so the
//!    threshold falls linearly from `min_red_excess` at `bright_knee` to `bright_red_excess` at
//!    255 (the adaptive brightness term). Cells darker than a floor proportional to the frame's
//!    mean brightness carry no reliable colour and count as background.
//! 3. Over-exposed cells without usable colour are unknown. Their connected blobs are sorted by
//!    `saturated_blobs`: a blob ringed by apple colour is a highlight and joins the fruit;
//!    a disc-shaped, apple-sized blob without a red ring (a wholly blown-out fruit) becomes a
//!    [`DetectionSource::SaturatedBlob`] candidate for depth confirmation; the rest join an apple
//!    region only when it reaches them within `highlight_fill_iterations` cells.
//! 4. Opening then closing with a 3x3 square removes specks and bridges one-cell gaps.
//! 5. 8-connected components; each is split into apples by `touching_split`.
//! 6. Per apple: box, mask, visible pixels and a confidence combining colour margin, roundness,
//!    size and exposure.

use serde::{Deserialize, Serialize};
use thiserror::Error;
use tracing::trace;

use super::components::Components;
use super::distance_transform::chamfer_distance;
use super::morphology;
use super::saturated_blobs::class::{APPLE, BACKGROUND, UNKNOWN};
use super::saturated_blobs::{BlobParams, SaturatedBlobs};
use super::touching_split::{Seed, SplitParams, find_seeds, nearest_seed};
use super::{Detection, DetectionMask, DetectionSource, Detector, DetectorFrameInfo, PixelBox};
use crate::frame::{FrameError, RgbView};

/// Parameters of [`ColorSegmentation`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ColorSegmentationConfig {
    /// Side of one analysis cell in colour pixels (4: 1920x1080 -> 480x270 cells).
    pub downscale: u32,
    /// Every `row_sampling_step`-th pixel row of a cell enters its mean colour (speed; 1 = all).
    pub row_sampling_step: u32,
    /// Minimum red excess `r - g` in normalized chromaticity for an apple cell.
    pub min_red_excess: f32,
    /// Minimum red excess for a cell whose brightest channel is at 255.
    pub bright_red_excess: f32,
    /// Brightest-channel value (0-255) above which the red-excess threshold starts to fall.
    pub bright_knee: f32,
    /// Maximum blue chromaticity `b = B/(R+G+B)` of an apple cell (rejects purple and sky).
    pub max_blue_chromaticity: f32,
    /// Dark floor as a fraction of the frame's mean brightest-channel value.
    pub dark_floor_fraction: f32,
    /// Lower clamp of the dark floor (0-255).
    pub dark_floor_min: f32,
    /// Upper clamp of the dark floor (0-255).
    pub dark_floor_max: f32,
    /// A pixel whose brightest channel reaches this value is clipped (over-exposed).
    pub clip_level: u8,
    /// How many cells an apple region may grow into over-exposed cells of unknown colour.
    pub highlight_fill_iterations: u32,
    /// Minimum apple area in cells.
    pub min_area_cells: u32,
    /// Minimum inscribed radius of an apple (cells); thinner regions are not apples.
    pub min_seed_radius_cells: f32,
    /// A further apple seed in a region must reach this fraction of the region's largest radius.
    pub seed_relative_radius: f32,
    /// Seeds closer than this factor times the larger inscribed radius belong to one apple.
    pub seed_separation_factor: f32,
    /// Seeds are split only when the neck between them is below this fraction of the smaller
    /// inscribed radius. Cell averaging and closing thicken necks, so overlapping fruit show
    /// ratios of 0.8-0.85; a fruit wrongly split at a rim notch is re-merged in 3D.
    pub saddle_ratio: f32,
    /// Maximum apples per connected region.
    pub max_seeds_per_region: u32,
    /// Report disc-shaped over-exposed blobs as candidates for depth confirmation.
    pub detect_saturated_blobs: bool,
    /// An over-exposed blob whose outer ring holds at least this fraction of apple cells is a
    /// highlight of that fruit and joins it.
    pub highlight_ring_fraction: f32,
    /// Largest inscribed radius of a saturated-blob candidate, cells (the nearest, largest
    /// apple: 50 mm at 0.5 m is 160 px = 40 cells with the TL460 colour lens).
    pub max_blob_radius_cells: f32,
    /// Largest fill ratio `area / (pi r_in^2)` of a saturated-blob candidate (1 for a disc).
    pub max_blob_fill_ratio: f32,
    /// Detection confidence of a saturated-blob candidate of ideal shape and size, before depth
    /// confirmation (colour gives no evidence).
    pub blob_confidence: f32,
}

impl Default for ColorSegmentationConfig {
    fn default() -> Self {
        Self {
            downscale: 4,
            row_sampling_step: 2,
            min_red_excess: 0.20,
            bright_red_excess: 0.08,
            bright_knee: 210.0,
            max_blue_chromaticity: 0.40,
            dark_floor_fraction: 0.25,
            dark_floor_min: 20.0,
            dark_floor_max: 50.0,
            clip_level: 250,
            highlight_fill_iterations: 4,
            min_area_cells: 10,
            min_seed_radius_cells: 2.0,
            seed_relative_radius: 0.35,
            seed_separation_factor: 0.9,
            saddle_ratio: 0.9,
            max_seeds_per_region: 12,
            detect_saturated_blobs: true,
            highlight_ring_fraction: 0.5,
            max_blob_radius_cells: 48.0,
            max_blob_fill_ratio: 2.0,
            blob_confidence: 0.6,
        }
    }
}

/// A [`ColorSegmentationConfig`] value that cannot be used.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ColorSegmentationConfigError {
    /// `downscale` must be 1..=32.
    #[error("colour segmentation: downscale = {value} is outside 1..=32")]
    Downscale { value: u32 },
    /// `row_sampling_step` must be 1..=downscale.
    #[error(
        "colour segmentation: row_sampling_step = {value} is outside 1..={downscale} (downscale)"
    )]
    RowSampling { value: u32, downscale: u32 },
    /// `max_seeds_per_region` must be 1..=255.
    #[error("colour segmentation: max_seeds_per_region = {value} is outside 1..=255")]
    MaxSeeds { value: u32 },
    /// A real-valued parameter is not finite or outside its range.
    #[error("colour segmentation: {key} = {value} is not finite or outside {min}..={max}")]
    OutOfRange {
        key: &'static str,
        value: f32,
        min: f32,
        max: f32,
    },
}

impl ColorSegmentationConfig {
    /// Checks every parameter against its physical range.
    pub fn validate(&self) -> Result<(), ColorSegmentationConfigError> {
        if !(1..=32).contains(&self.downscale) {
            return Err(ColorSegmentationConfigError::Downscale {
                value: self.downscale,
            });
        }
        if !(1..=self.downscale).contains(&self.row_sampling_step) {
            return Err(ColorSegmentationConfigError::RowSampling {
                value: self.row_sampling_step,
                downscale: self.downscale,
            });
        }
        if !(1..=255).contains(&self.max_seeds_per_region) {
            return Err(ColorSegmentationConfigError::MaxSeeds {
                value: self.max_seeds_per_region,
            });
        }
        let checks: [(&'static str, f32, f32, f32); 15] = [
            ("min_red_excess", self.min_red_excess, -1.0, 1.0),
            ("bright_red_excess", self.bright_red_excess, -1.0, 1.0),
            ("bright_knee", self.bright_knee, 0.0, 254.0),
            (
                "max_blue_chromaticity",
                self.max_blue_chromaticity,
                0.0,
                1.0,
            ),
            ("dark_floor_fraction", self.dark_floor_fraction, 0.0, 1.0),
            ("dark_floor_min", self.dark_floor_min, 0.0, 255.0),
            (
                "dark_floor_max",
                self.dark_floor_max,
                self.dark_floor_min,
                255.0,
            ),
            (
                "min_seed_radius_cells",
                self.min_seed_radius_cells,
                0.5,
                1000.0,
            ),
            ("seed_relative_radius", self.seed_relative_radius, 0.0, 1.0),
            (
                "seed_separation_factor",
                self.seed_separation_factor,
                0.0,
                2.0,
            ),
            ("saddle_ratio", self.saddle_ratio, 0.0, 1.0),
            (
                "highlight_ring_fraction",
                self.highlight_ring_fraction,
                0.0,
                1.0,
            ),
            (
                "max_blob_radius_cells",
                self.max_blob_radius_cells,
                self.min_seed_radius_cells,
                1000.0,
            ),
            ("max_blob_fill_ratio", self.max_blob_fill_ratio, 1.0, 100.0),
            ("blob_confidence", self.blob_confidence, 0.0, 1.0),
        ];
        for (key, value, min, max) in checks {
            if !value.is_finite() || value < min || value > max {
                return Err(ColorSegmentationConfigError::OutOfRange {
                    key,
                    value,
                    min,
                    max,
                });
            }
        }
        Ok(())
    }
}

/// The classical colour-segmentation detector. Holds its scratch buffers between frames.
#[derive(Debug)]
pub struct ColorSegmentation {
    config: ColorSegmentationConfig,
    row_sums: Vec<[u32; 4]>,
    mean_rgb: Vec<[f32; 3]>,
    overexposed: Vec<u8>,
    class: Vec<u8>,
    margin: Vec<f32>,
    mask: Vec<u8>,
    scratch_a: Vec<u8>,
    scratch_b: Vec<u8>,
    distance: Vec<u16>,
    components: Components,
    candidates: Vec<(u16, u32)>,
    seeds: Vec<Seed>,
    assignment: Vec<u8>,
    regions: Vec<RegionSums>,
    blobs: SaturatedBlobs,
    blob_mask: Vec<u8>,
}

/// Running sums of one apple region.
#[derive(Debug, Clone, Copy)]
struct RegionSums {
    x_min: usize,
    x_max: usize,
    y_min: usize,
    y_max: usize,
    area_cells: u32,
    margin_sum: f32,
    overexposed_cells: u32,
}

impl RegionSums {
    const EMPTY: Self = Self {
        x_min: usize::MAX,
        x_max: 0,
        y_min: usize::MAX,
        y_max: 0,
        area_cells: 0,
        margin_sum: 0.0,
        overexposed_cells: 0,
    };
}

impl ColorSegmentation {
    /// A detector with validated parameters.
    pub fn new(config: ColorSegmentationConfig) -> Result<Self, ColorSegmentationConfigError> {
        config.validate()?;
        Ok(Self {
            config,
            row_sums: Vec::new(),
            mean_rgb: Vec::new(),
            overexposed: Vec::new(),
            class: Vec::new(),
            margin: Vec::new(),
            mask: Vec::new(),
            scratch_a: Vec::new(),
            scratch_b: Vec::new(),
            distance: Vec::new(),
            components: Components::default(),
            candidates: Vec::new(),
            seeds: Vec::new(),
            assignment: Vec::new(),
            regions: Vec::new(),
            blobs: SaturatedBlobs::default(),
            blob_mask: Vec::new(),
        })
    }

    pub fn config(&self) -> &ColorSegmentationConfig {
        &self.config
    }

    /// Step 1: mean colour and clipped-majority flag of every cell (over the sampled rows).
    fn downsample(&mut self, rgb: &RgbView<'_>, grid_w: usize, grid_h: usize) {
        let s = self.config.downscale as usize;
        let width = rgb.width_px as usize;
        let cells = grid_w * grid_h;
        self.mean_rgb.clear();
        self.mean_rgb.resize(cells, [0.0; 3]);
        self.overexposed.clear();
        self.overexposed.resize(cells, 0);
        self.row_sums.clear();
        self.row_sums.resize(grid_w, [0; 4]);
        let clip = self.config.clip_level;
        let step = self.config.row_sampling_step as usize;
        let pixels_per_cell = (s * s.div_ceil(step)) as u32;
        let inverse = 1.0 / pixels_per_cell as f32;
        for gy in 0..grid_h {
            self.row_sums.fill([0; 4]);
            for row in (gy * s..(gy + 1) * s).step_by(step) {
                let start = row * width * 3;
                let Some(line) = rgb.data.get(start..start + grid_w * s * 3) else {
                    continue;
                };
                for (sums, block) in self.row_sums.iter_mut().zip(line.chunks_exact(3 * s)) {
                    // Local accumulators keep the per-pixel work in registers.
                    let (mut r, mut g, mut b, mut clipped) = (0_u32, 0_u32, 0_u32, 0_u32);
                    for px in block.chunks_exact(3) {
                        r += u32::from(px[0]);
                        g += u32::from(px[1]);
                        b += u32::from(px[2]);
                        clipped += u32::from(px[0].max(px[1]).max(px[2]) >= clip);
                    }
                    sums[0] += r;
                    sums[1] += g;
                    sums[2] += b;
                    sums[3] += clipped;
                }
            }
            let base = gy * grid_w;
            for (gx, sums) in self.row_sums.iter().enumerate() {
                self.mean_rgb[base + gx] = [
                    sums[0] as f32 * inverse,
                    sums[1] as f32 * inverse,
                    sums[2] as f32 * inverse,
                ];
                self.overexposed[base + gx] = u8::from(2 * sums[3] >= pixels_per_cell);
            }
        }
    }

    /// Step 2: apple / background / unknown per cell, red-excess margin, and the initial mask.
    /// Returns the number of over-exposed cells.
    fn classify(&mut self) -> usize {
        let c = &self.config;
        let cells = self.mean_rgb.len();
        self.class.clear();
        self.class.resize(cells, BACKGROUND);
        self.margin.clear();
        self.margin.resize(cells, 0.0);
        self.mask.clear();
        self.mask.resize(cells, 0);
        if cells == 0 {
            return 0;
        }
        let mean_brightness = self
            .mean_rgb
            .iter()
            .map(|p| p[0].max(p[1]).max(p[2]))
            .sum::<f32>()
            / cells as f32;
        let dark_floor =
            (c.dark_floor_fraction * mean_brightness).clamp(c.dark_floor_min, c.dark_floor_max);
        let knee_span = (255.0 - c.bright_knee).max(1.0);
        let mut overexposed_cells = 0;
        for i in 0..cells {
            let [r, g, b] = self.mean_rgb[i];
            let brightness = r.max(g).max(b);
            let clipped = self.overexposed[i] != 0;
            overexposed_cells += usize::from(clipped);
            if brightness < dark_floor && !clipped {
                continue;
            }
            let sum = r + g + b;
            let red_excess = (r - g) / sum;
            let blue = b / sum;
            let brightness_t = ((brightness - c.bright_knee) / knee_span).clamp(0.0, 1.0);
            let threshold =
                c.min_red_excess + (c.bright_red_excess - c.min_red_excess) * brightness_t;
            if r >= b && red_excess >= threshold && blue <= c.max_blue_chromaticity {
                self.class[i] = APPLE;
                self.margin[i] = red_excess - threshold;
                self.mask[i] = 1;
            } else if clipped {
                self.class[i] = UNKNOWN;
            }
        }
        overexposed_cells
    }

    /// Step 3: grow apple regions into adjacent over-exposed cells of unknown colour.
    fn absorb_highlights(&mut self, grid_w: usize, grid_h: usize) {
        if !self.class.contains(&UNKNOWN) {
            return;
        }
        for _ in 0..self.config.highlight_fill_iterations {
            self.scratch_a.clear();
            self.scratch_a.extend_from_slice(&self.mask);
            let mut changed = false;
            for y in 0..grid_h {
                for x in 0..grid_w {
                    let i = y * grid_w + x;
                    if self.class[i] != UNKNOWN || self.mask[i] != 0 {
                        continue;
                    }
                    let touches = (y.saturating_sub(1)..=(y + 1).min(grid_h - 1)).any(|ny| {
                        (x.saturating_sub(1)..=(x + 1).min(grid_w - 1))
                            .any(|nx| self.mask[ny * grid_w + nx] != 0)
                    });
                    if touches {
                        self.scratch_a[i] = 1;
                        changed = true;
                    }
                }
            }
            std::mem::swap(&mut self.mask, &mut self.scratch_a);
            if !changed {
                break;
            }
        }
    }

    /// Steps 5-6 for one connected component: seeds, assignment, one detection per seed.
    fn extract_component(
        &mut self,
        component: usize,
        grid_w: usize,
        grid_h: usize,
        image: (u32, u32),
        source: DetectionSource,
        detections: &mut Vec<Detection>,
    ) -> bool {
        let params = SplitParams {
            min_seed_radius_cells: self.config.min_seed_radius_cells,
            seed_relative_radius: self.config.seed_relative_radius,
            seed_separation_factor: self.config.seed_separation_factor,
            saddle_ratio: self.config.saddle_ratio,
            max_seeds: self.config.max_seeds_per_region as usize,
        };
        let cells = self.components.cells(component);
        if cells.len() < self.config.min_area_cells as usize {
            return false;
        }
        find_seeds(
            cells,
            &self.distance,
            grid_w,
            grid_h,
            &params,
            &mut self.candidates,
            &mut self.seeds,
        );
        if self.seeds.is_empty() {
            return false;
        }
        self.assignment.clear();
        self.regions.clear();
        self.regions.resize(self.seeds.len(), RegionSums::EMPTY);
        for &index in cells {
            let index = index as usize;
            let (x, y) = (index % grid_w, index / grid_w);
            let k = if self.seeds.len() == 1 {
                0
            } else {
                nearest_seed(x as f32, y as f32, &self.seeds)
            };
            self.assignment.push(k as u8);
            let region = &mut self.regions[k];
            region.x_min = region.x_min.min(x);
            region.x_max = region.x_max.max(x);
            region.y_min = region.y_min.min(y);
            region.y_max = region.y_max.max(y);
            region.area_cells += 1;
            region.margin_sum += self.margin[index];
            region.overexposed_cells += u32::from(self.overexposed[index]);
        }
        let s = self.config.downscale;
        let (image_w, image_h) = image;
        for (k, (region, seed)) in self.regions.iter().zip(self.seeds.iter()).enumerate() {
            if region.area_cells < self.config.min_area_cells {
                continue;
            }
            let width_cells = (region.x_max - region.x_min + 1) as u32;
            let height_cells = (region.y_max - region.y_min + 1) as u32;
            let mut mask = DetectionMask::new(
                region.x_min as u32 * s,
                region.y_min as u32 * s,
                s,
                width_cells,
                height_cells,
            );
            for (&index, &owner) in cells.iter().zip(self.assignment.iter()) {
                if owner as usize == k {
                    let index = index as usize;
                    mask.set_cell(
                        (index % grid_w - region.x_min) as u32,
                        (index / grid_w - region.y_min) as u32,
                        true,
                    );
                }
            }
            let area = region.area_cells as f32;
            let saturated_fraction = region.overexposed_cells as f32 / area;
            let confidence = match source {
                // (This detector reports no `Model` detections.)
                DetectionSource::Colour | DetectionSource::Model => region_confidence(
                    region.margin_sum / area,
                    area,
                    seed.radius_cells,
                    saturated_fraction,
                ),
                DetectionSource::SaturatedBlob => {
                    self.config.blob_confidence * shape_size_factor(area, seed.radius_cells)
                }
            };
            detections.push(Detection {
                pixel_box: PixelBox {
                    u_min_px: region.x_min as u32 * s,
                    v_min_px: region.y_min as u32 * s,
                    u_max_px: ((region.x_max as u32 + 1) * s).min(image_w),
                    v_max_px: ((region.y_max as u32 + 1) * s).min(image_h),
                },
                mask,
                visible_px: region.area_cells * s * s,
                confidence,
                saturated_fraction,
                source,
            });
        }
        self.seeds.len() > 1
    }
}

/// Mask-derived confidence in [0, 1]: colour margin (0.4 at the threshold, 1 at 0.3 above it),
/// roundness (area over the inscribed-circle area; elongated regions lose), size (full from an
/// inscribed radius of 3 cells) and exposure (clipped cells halve their share).
fn region_confidence(mean_margin: f32, area_cells: f32, radius_cells: f32, saturated: f32) -> f32 {
    let colour = (0.4 + 2.0 * mean_margin).clamp(0.0, 1.0);
    let exposure = 1.0 - 0.5 * saturated.clamp(0.0, 1.0);
    (colour * shape_size_factor(area_cells, radius_cells) * exposure).clamp(0.0, 1.0)
}

/// Shape and size part of the confidence: roundness (area over the inscribed-circle area) times
/// size (full from an inscribed radius of 3 cells), in [0, 1].
fn shape_size_factor(area_cells: f32, radius_cells: f32) -> f32 {
    let disc_area = std::f32::consts::PI * radius_cells * radius_cells;
    let fill = area_cells / disc_area.max(1.0);
    let shape = (1.3 / fill.max(1e-3)).min(1.0);
    let size = (radius_cells / 3.0).min(1.0);
    (shape * size).clamp(0.0, 1.0)
}

impl Detector for ColorSegmentation {
    fn name(&self) -> &'static str {
        "color_segmentation"
    }

    fn detect(
        &mut self,
        rgb: &RgbView<'_>,
        detections: &mut Vec<Detection>,
    ) -> Result<DetectorFrameInfo, FrameError> {
        detections.clear();
        rgb.validate()?;
        let s = self.config.downscale as usize;
        let grid_w = rgb.width_px as usize / s;
        let grid_h = rgb.height_px as usize / s;
        if grid_w == 0 || grid_h == 0 {
            return Ok(DetectorFrameInfo::default());
        }
        self.downsample(rgb, grid_w, grid_h);
        let overexposed_cells = self.classify();
        let blob_counts = if self.config.detect_saturated_blobs {
            let params = BlobParams {
                min_area_cells: self.config.min_area_cells,
                min_radius_cells: self.config.min_seed_radius_cells,
                max_radius_cells: self.config.max_blob_radius_cells,
                max_fill_ratio: self.config.max_blob_fill_ratio,
                highlight_ring_fraction: self.config.highlight_ring_fraction,
            };
            self.blobs.sort(
                &mut self.class,
                &mut self.mask,
                &mut self.blob_mask,
                grid_w,
                grid_h,
                &params,
            )
        } else {
            Default::default()
        };
        self.absorb_highlights(grid_w, grid_h);
        morphology::open(
            &mut self.mask,
            grid_w,
            grid_h,
            &mut self.scratch_a,
            &mut self.scratch_b,
        );
        morphology::close(
            &mut self.mask,
            grid_w,
            grid_h,
            &mut self.scratch_a,
            &mut self.scratch_b,
        );
        chamfer_distance(&self.mask, grid_w, grid_h, &mut self.distance);
        self.components.label(&self.mask, grid_w, grid_h);
        let candidate_regions = self.components.count() as u32;
        let mut split_regions = 0;
        for component in 0..self.components.count() {
            let split = self.extract_component(
                component,
                grid_w,
                grid_h,
                (rgb.width_px, rgb.height_px),
                DetectionSource::Colour,
                detections,
            );
            split_regions += u32::from(split);
        }
        if blob_counts.candidates > 0 {
            // Blown-out fruit: the same seeds and split on the candidate blobs.
            chamfer_distance(&self.blob_mask, grid_w, grid_h, &mut self.distance);
            self.components.label(&self.blob_mask, grid_w, grid_h);
            for component in 0..self.components.count() {
                let split = self.extract_component(
                    component,
                    grid_w,
                    grid_h,
                    (rgb.width_px, rgb.height_px),
                    DetectionSource::SaturatedBlob,
                    detections,
                );
                split_regions += u32::from(split);
            }
        }
        let saturated_fraction = overexposed_cells as f32 / (grid_w * grid_h) as f32;
        trace!(
            candidate_regions,
            split_regions,
            detections = detections.len(),
            saturated_fraction,
            "colour segmentation"
        );
        Ok(DetectorFrameInfo {
            saturated_fraction,
            candidate_regions,
            split_regions,
            highlights_filled: blob_counts.highlights,
            saturated_blobs: blob_counts.candidates,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const W: usize = 640;
    const H: usize = 480;

    /// Deterministic pixel noise in [-0.5, 0.5).
    fn noise(x: usize, y: usize) -> f32 {
        let h = (x as u32).wrapping_mul(0x9E37_79B1) ^ (y as u32).wrapping_mul(0x85EB_CA77);
        let h = (h ^ (h >> 15)).wrapping_mul(0x2C1B_3C6D);
        ((h ^ (h >> 12)) & 0xFFFF) as f32 / 65536.0 - 0.5
    }

    /// Leaf texture: green with blotches and pixel noise, a brown branch and a sky band on top.
    fn background() -> Vec<u8> {
        let mut image = vec![0_u8; W * H * 3];
        for y in 0..H {
            for x in 0..W {
                let blotch = ((x as f32 / 23.0).sin() * (y as f32 / 17.0).cos() + 1.0) / 2.0;
                let n = noise(x, y) * 30.0;
                let rgb = if y < 60 {
                    [160.0 + n * 0.2, 200.0, 245.0]
                } else if (x as i32 - y as i32 - 100).abs() < 6 {
                    [100.0 + n, 72.0 + n, 50.0]
                } else {
                    [
                        30.0 + 80.0 * blotch + n,
                        70.0 + 90.0 * blotch + n,
                        25.0 + 30.0 * blotch + n,
                    ]
                };
                let i = (y * W + x) * 3;
                for c in 0..3 {
                    image[i + c] = rgb[c].clamp(0.0, 255.0) as u8;
                }
            }
        }
        image
    }

    /// A shaded red disc (light from the upper left) with a clipped specular highlight.
    fn draw_apple(image: &mut [u8], cx: f32, cy: f32, radius: f32, gain: f32) {
        for y in 0..H {
            for x in 0..W {
                let (dx, dy) = ((x as f32 - cx) / radius, (y as f32 - cy) / radius);
                let rho_sq = dx * dx + dy * dy;
                if rho_sq > 1.0 {
                    continue;
                }
                let nz = (1.0 - rho_sq).sqrt();
                let diffuse = (-0.4 * dx - 0.5 * dy + 0.77 * nz).max(0.0);
                let shade = 0.3 + 0.7 * diffuse;
                let highlight = if (dx + 0.3).powi(2) + (dy + 0.35).powi(2) < 0.02 {
                    400.0
                } else {
                    0.0
                };
                let n = noise(x, y) * 8.0;
                let rgb = [200.0 * shade, 25.0 * shade, 30.0 * shade];
                let i = (y * W + x) * 3;
                for c in 0..3 {
                    image[i + c] = ((rgb[c] + highlight + n) * gain).clamp(0.0, 255.0) as u8;
                }
            }
        }
    }

    fn detect(image: &[u8]) -> (Vec<Detection>, DetectorFrameInfo) {
        let mut detector =
            ColorSegmentation::new(ColorSegmentationConfig::default()).expect("valid");
        let mut detections = Vec::new();
        let info = detector
            .detect(
                &RgbView {
                    width_px: W as u32,
                    height_px: H as u32,
                    data: image,
                },
                &mut detections,
            )
            .expect("valid frame");
        (detections, info)
    }

    /// Index of the confident detection whose box contains `(x, y)`.
    fn covering(detections: &[Detection], x: f32, y: f32) -> Vec<usize> {
        detections
            .iter()
            .enumerate()
            .filter(|(_, d)| d.confidence >= 0.3 && d.pixel_box.contains(x as u32, y as u32))
            .map(|(i, _)| i)
            .collect()
    }

    #[test]
    fn shaded_apples_on_leaves_are_detected_with_tight_boxes() {
        let mut image = background();
        let apples = [
            (120.0, 150.0, 30.0),
            (400.0, 300.0, 45.0),
            (550.0, 120.0, 18.0),
        ];
        for &(x, y, r) in &apples {
            draw_apple(&mut image, x, y, r, 1.0);
        }
        let (detections, _) = detect(&image);
        let confident: Vec<&Detection> =
            detections.iter().filter(|d| d.confidence >= 0.3).collect();
        assert_eq!(confident.len(), apples.len(), "{detections:?}");
        for &(x, y, r) in &apples {
            let hits = covering(&detections, x, y);
            assert_eq!(hits.len(), 1, "apple at ({x}, {y})");
            let d = &detections[hits[0]];
            let (u, v) = d.pixel_box.center_px();
            assert!(
                (u as f32 - x).abs() < 0.25 * r && (v as f32 - y).abs() < 0.25 * r,
                "{d:?}"
            );
            assert!(
                (d.pixel_box.width_px() as f32 - 2.0 * r).abs() < 0.35 * r,
                "{:?}",
                d.pixel_box
            );
            let disc_px = std::f32::consts::PI * r * r;
            assert!(
                (d.visible_px as f32 / disc_px - 1.0).abs() < 0.3,
                "visible {} vs {disc_px}",
                d.visible_px
            );
            assert!(d.mask.contains_px(x as u32, y as u32));
            assert!(!d.mask.contains_px((x + 1.3 * r) as u32, y as u32));
        }
    }

    #[test]
    fn touching_apples_are_split_into_two() {
        for (r1, r2, gap) in [(40.0, 40.0, 0.0), (40.0, 30.0, -6.0), (35.0, 35.0, -12.0)] {
            let mut image = background();
            let (x1, y) = (250.0, 250.0);
            let x2 = x1 + r1 + r2 + gap;
            draw_apple(&mut image, x1, y, r1, 1.0);
            draw_apple(&mut image, x2, y, r2, 1.0);
            let (detections, info) = detect(&image);
            let confident = detections.iter().filter(|d| d.confidence >= 0.3).count();
            assert_eq!(confident, 2, "radii {r1}/{r2}, gap {gap}: {detections:?}");
            assert_eq!(info.split_regions, 1);
            let left = covering(&detections, x1 - 0.5 * r1, y);
            let right = covering(&detections, x2 + 0.5 * r2, y);
            assert_eq!(left.len(), 1);
            assert_eq!(right.len(), 1);
            assert_ne!(left, right);
            // Each mask holds its own centre, not the other's.
            assert!(detections[left[0]].mask.contains_px(x1 as u32, y as u32));
            assert!(!detections[left[0]].mask.contains_px(x2 as u32, y as u32));
        }
    }

    #[test]
    fn frames_without_apples_yield_nothing() {
        let (leaves, _) = detect(&background());
        assert!(leaves.iter().all(|d| d.confidence < 0.3), "{leaves:?}");
        for value in [0_u8, 128] {
            let (flat, _) = detect(&vec![value; W * H * 3]);
            assert!(flat.is_empty());
        }
        let (white, info) = detect(&vec![255_u8; W * H * 3]);
        assert!(white.is_empty());
        assert!(info.saturated_fraction > 0.99);
    }

    #[test]
    fn over_exposed_and_dim_apples_are_still_found() {
        for gain in [0.35, 1.8] {
            let mut image = background();
            for byte in &mut image {
                *byte = (f32::from(*byte) * gain).clamp(0.0, 255.0) as u8;
            }
            draw_apple(&mut image, 200.0, 200.0, 40.0, gain);
            let (detections, info) = detect(&image);
            let hits = covering(&detections, 200.0, 200.0);
            assert_eq!(hits.len(), 1, "gain {gain}: {detections:?}");
            if gain > 1.0 {
                assert!(info.saturated_fraction > 0.0);
                // The highlight is part of the mask.
                assert!(detections[hits[0]].mask.contains_px(188, 186));
            }
        }
    }

    /// Whites out a disc, like sunlight saturating a whole fruit and the leaves around it.
    fn blow_out(image: &mut [u8], cx: f32, cy: f32, radius: f32) {
        for y in 0..H {
            for x in 0..W {
                if (x as f32 - cx).powi(2) + (y as f32 - cy).powi(2) <= radius * radius {
                    image[(y * W + x) * 3..(y * W + x) * 3 + 3].fill(255);
                }
            }
        }
    }

    #[test]
    fn wholly_blown_out_apple_is_a_saturated_blob_candidate() {
        let mut image = background();
        draw_apple(&mut image, 200.0, 250.0, 40.0, 1.0);
        blow_out(&mut image, 200.0, 250.0, 42.0);
        draw_apple(&mut image, 450.0, 300.0, 35.0, 1.0);
        let (detections, info) = detect(&image);
        assert_eq!(info.saturated_blobs, 1, "{info:?}");
        let hits = covering(&detections, 200.0, 250.0);
        assert_eq!(hits.len(), 1, "{detections:?}");
        let blob = &detections[hits[0]];
        assert_eq!(blob.source, DetectionSource::SaturatedBlob);
        assert!(blob.saturated_fraction > 0.9);
        let (u, v) = blob.pixel_box.center_px();
        assert!(
            (u - 200.0).abs() < 6.0 && (v - 250.0).abs() < 6.0,
            "{blob:?}"
        );
        let disc_px = std::f32::consts::PI * 42.0 * 42.0;
        assert!((blob.visible_px as f32 / disc_px - 1.0).abs() < 0.3);
        // The ordinary apple is still a colour detection.
        let red = covering(&detections, 450.0, 300.0);
        assert_eq!(red.len(), 1);
        assert_eq!(detections[red[0]].source, DetectionSource::Colour);
    }

    #[test]
    fn blown_out_centre_ringed_by_red_stays_one_colour_apple() {
        let mut image = background();
        draw_apple(&mut image, 300.0, 250.0, 60.0, 1.0);
        blow_out(&mut image, 300.0, 250.0, 35.0);
        let (detections, info) = detect(&image);
        assert_eq!(info.highlights_filled, 1, "{info:?}");
        assert_eq!(info.saturated_blobs, 0);
        let hits = covering(&detections, 300.0, 250.0);
        assert_eq!(hits.len(), 1, "{detections:?}");
        let apple = &detections[hits[0]];
        assert_eq!(apple.source, DetectionSource::Colour);
        assert!(
            apple.mask.contains_px(300, 250),
            "the highlight is part of the fruit"
        );
    }

    #[test]
    fn white_background_alone_is_not_an_apple() {
        // White sky over the top quarter, and a white frame.
        let mut image = background();
        image[..W * 120 * 3].fill(255);
        let (detections, info) = detect(&image);
        assert!(
            detections.iter().all(|d| d.confidence < 0.3),
            "{detections:?}"
        );
        assert_eq!(info.saturated_blobs, 0);
        let (white, info) = detect(&vec![255_u8; W * H * 3]);
        assert!(white.is_empty());
        assert_eq!(info.saturated_blobs, 0);
    }

    #[test]
    fn wrong_buffer_size_is_an_error_and_clears_detections() {
        let mut detector =
            ColorSegmentation::new(ColorSegmentationConfig::default()).expect("valid");
        let mut detections = vec![];
        let data = vec![0_u8; 100];
        let result = detector.detect(
            &RgbView {
                width_px: 64,
                height_px: 64,
                data: &data,
            },
            &mut detections,
        );
        assert!(matches!(result, Err(FrameError::RgbBufferSize { .. })));
        assert!(detections.is_empty());
        let tiny = vec![200_u8; 2 * 2 * 3];
        let info = detector
            .detect(
                &RgbView {
                    width_px: 2,
                    height_px: 2,
                    data: &tiny,
                },
                &mut detections,
            )
            .expect("valid, smaller than one cell");
        assert!(detections.is_empty());
        assert_eq!(info, DetectorFrameInfo::default());
    }

    #[test]
    fn invalid_config_is_rejected() {
        let config = ColorSegmentationConfig {
            downscale: 0,
            ..ColorSegmentationConfig::default()
        };
        assert!(matches!(
            ColorSegmentation::new(config),
            Err(ColorSegmentationConfigError::Downscale { value: 0 })
        ));
        let config = ColorSegmentationConfig {
            min_red_excess: f32::NAN,
            ..ColorSegmentationConfig::default()
        };
        assert!(matches!(
            ColorSegmentation::new(config),
            Err(ColorSegmentationConfigError::OutOfRange {
                key: "min_red_excess",
                ..
            })
        ));
    }
}
