//! 2D apple detection in the colour image.
//!
//! A [`Detector`] turns one colour frame into a list of [`Detection`]s: a pixel box, a pixel mask,
//! the number of visible apple pixels and a confidence in [0, 1]. The paper ([dual-arm sec.
//! 3.1.1-3.1.2]) uses a fine-tuned Grounding-DINO detector with a prompt-guided instance segmenter
//! and a 0.3 confidence threshold. Two implementations, chosen in one place ([`choice`], the
//! `[detector]` table of perception's config):
//! - [`color_segmentation::ColorSegmentation`] (default): classical, needs no model;
//! - [`onnx::OnnxDetector`]: a YOLOv8/YOLO11 detect or segment model exported to ONNX
//!   (decoding in [`yolo`]; the runtime behind the `onnx` cargo feature).

pub mod choice;
pub mod color_segmentation;
mod components;
mod distance_transform;
mod morphology;
pub mod onnx;
mod saturated_blobs;
mod touching_split;
pub mod yolo;

pub use choice::{DetectorConfig, DetectorKind, make_detector};

use serde::Serialize;

use crate::frame::{FrameError, RgbView};

/// An axis-aligned pixel box in the full-resolution colour image, half-open:
/// `u_min_px <= u < u_max_px`, `v_min_px <= v < v_max_px`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct PixelBox {
    pub u_min_px: u32,
    pub v_min_px: u32,
    pub u_max_px: u32,
    pub v_max_px: u32,
}

impl PixelBox {
    pub fn width_px(&self) -> u32 {
        self.u_max_px.saturating_sub(self.u_min_px)
    }

    pub fn height_px(&self) -> u32 {
        self.v_max_px.saturating_sub(self.v_min_px)
    }

    /// Centre of the box in pixel coordinates (pixel centres at integers).
    pub fn center_px(&self) -> (f64, f64) {
        (
            (self.u_min_px as f64 + self.u_max_px as f64 - 1.0) / 2.0,
            (self.v_min_px as f64 + self.v_max_px as f64 - 1.0) / 2.0,
        )
    }

    /// Smallest box containing both boxes.
    pub fn union(&self, other: &Self) -> Self {
        Self {
            u_min_px: self.u_min_px.min(other.u_min_px),
            v_min_px: self.v_min_px.min(other.v_min_px),
            u_max_px: self.u_max_px.max(other.u_max_px),
            v_max_px: self.v_max_px.max(other.v_max_px),
        }
    }

    /// True when the pixel `(u_px, v_px)` lies in the box.
    pub fn contains(&self, u_px: u32, v_px: u32) -> bool {
        u_px >= self.u_min_px
            && u_px < self.u_max_px
            && v_px >= self.v_min_px
            && v_px < self.v_max_px
    }
}

/// A binary apple mask stored on a grid of square cells of `cell_px` colour pixels, covering the
/// detection box. `cell_px = 1` is a full-resolution mask (e.g. from a learned segmenter).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DetectionMask {
    /// Full-resolution pixel of the top-left corner of cell (0, 0).
    pub origin_u_px: u32,
    pub origin_v_px: u32,
    /// Side of one cell in colour pixels (>= 1).
    pub cell_px: u32,
    pub width_cells: u32,
    pub height_cells: u32,
    /// Row-major cell flags, `width_cells * height_cells` entries.
    cells: Vec<bool>,
}

impl DetectionMask {
    /// An empty mask (all cells false). `cell_px` is clamped to at least 1.
    pub fn new(
        origin_u_px: u32,
        origin_v_px: u32,
        cell_px: u32,
        width_cells: u32,
        height_cells: u32,
    ) -> Self {
        Self {
            origin_u_px,
            origin_v_px,
            cell_px: cell_px.max(1),
            width_cells,
            height_cells,
            cells: vec![false; width_cells as usize * height_cells as usize],
        }
    }

    /// Sets one cell; out-of-range cells are ignored.
    pub fn set_cell(&mut self, cell_x: u32, cell_y: u32, value: bool) {
        if cell_x < self.width_cells && cell_y < self.height_cells {
            let index = cell_y as usize * self.width_cells as usize + cell_x as usize;
            if let Some(cell) = self.cells.get_mut(index) {
                *cell = value;
            }
        }
    }

    /// The flag of one cell; false outside the grid.
    pub fn cell(&self, cell_x: u32, cell_y: u32) -> bool {
        if cell_x >= self.width_cells || cell_y >= self.height_cells {
            return false;
        }
        let index = cell_y as usize * self.width_cells as usize + cell_x as usize;
        self.cells.get(index).copied().unwrap_or(false)
    }

    /// True when the full-resolution pixel `(u_px, v_px)` is an apple pixel.
    pub fn contains_px(&self, u_px: u32, v_px: u32) -> bool {
        if u_px < self.origin_u_px || v_px < self.origin_v_px {
            return false;
        }
        self.cell(
            (u_px - self.origin_u_px) / self.cell_px,
            (v_px - self.origin_v_px) / self.cell_px,
        )
    }

    /// Number of set cells.
    pub fn set_cell_count(&self) -> usize {
        self.cells.iter().filter(|&&c| c).count()
    }
}

/// What image evidence a detection rests on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum DetectionSource {
    /// An apple-coloured region (possibly with absorbed highlights).
    Colour,
    /// A disc-shaped, over-exposed region without usable colour (a blown-out fruit). Colour
    /// cannot tell it from white sky or a bright object, so the pipeline keeps it only when the
    /// registered depth confirms a solid, apple-sized object there.
    SaturatedBlob,
    /// A learned detector's detection (its mask, or the ellipse inscribed in its box).
    Model,
}

/// One apple seen in the colour image.
#[derive(Debug, Clone, PartialEq)]
pub struct Detection {
    /// Box around the mask, full-resolution colour pixels.
    pub pixel_box: PixelBox,
    pub mask: DetectionMask,
    /// Number of full-resolution pixels covered by the mask (visible apple area).
    pub visible_px: u32,
    /// Detection confidence in [0, 1] derived from the mask (colour, shape, size, exposure).
    pub confidence: f32,
    /// Fraction of the mask that was over-exposed (clipped colour), in [0, 1].
    pub saturated_fraction: f32,
    /// The evidence behind the detection.
    pub source: DetectionSource,
}

/// Frame-level information a detector reports besides its detections.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct DetectorFrameInfo {
    /// Fraction of the image that is over-exposed (colour clipped), in [0, 1].
    pub saturated_fraction: f32,
    /// Candidate regions before size filtering.
    pub candidate_regions: u32,
    /// Regions split into several apples (touching fruit).
    pub split_regions: u32,
    /// Over-exposed blobs ringed by apple colour, filled into the fruit around them.
    pub highlights_filled: u32,
    /// Disc-shaped over-exposed blobs reported as [`DetectionSource::SaturatedBlob`] candidates.
    pub saturated_blobs: u32,
}

/// A 2D apple detector.
pub trait Detector {
    /// Short name for logs.
    fn name(&self) -> &'static str;

    /// Detects apples in `rgb`, replacing the contents of `detections`. A malformed frame returns
    /// an error and leaves `detections` empty.
    fn detect(
        &mut self,
        rgb: &RgbView<'_>,
        detections: &mut Vec<Detection>,
    ) -> Result<DetectorFrameInfo, FrameError>;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mask_maps_full_resolution_pixels_to_cells() {
        let mut mask = DetectionMask::new(100, 40, 4, 3, 2);
        mask.set_cell(1, 1, true);
        mask.set_cell(7, 7, true); // ignored
        assert_eq!(mask.set_cell_count(), 1);
        assert!(mask.contains_px(104, 44));
        assert!(mask.contains_px(107, 47));
        assert!(!mask.contains_px(108, 47));
        assert!(!mask.contains_px(99, 44));
        assert!(!mask.contains_px(104, 39));
        assert!(!mask.contains_px(10_000, 10_000));
    }

    #[test]
    fn box_centre_and_union() {
        let a = PixelBox {
            u_min_px: 10,
            v_min_px: 20,
            u_max_px: 20,
            v_max_px: 40,
        };
        assert_eq!(a.center_px(), (14.5, 29.5));
        assert_eq!((a.width_px(), a.height_px()), (10, 20));
        let b = PixelBox {
            u_min_px: 5,
            v_min_px: 30,
            u_max_px: 12,
            v_max_px: 50,
        };
        assert_eq!(
            a.union(&b),
            PixelBox {
                u_min_px: 5,
                v_min_px: 20,
                u_max_px: 20,
                v_max_px: 50
            }
        );
        assert!(a.contains(10, 20) && !a.contains(20, 20));
    }
}
