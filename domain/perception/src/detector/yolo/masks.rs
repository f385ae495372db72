//! Apple masks in the full-resolution image from a YOLO detection.
//!
//! Segment head: the mask is `sigmoid(coefficients . prototypes)` on the prototype grid (a quarter
//! of the input's resolution), sampled bilinearly at each mask cell's centre carried back through
//! the letterbox, kept where it exceeds 0.5 and inside the detection's box (Ultralytics'
//! `process_mask`: crop to the box, upsample, threshold at 0.5). Detect head: no mask comes with
//! the box, and apples are round, so the mask is the ellipse inscribed in the box (the box's
//! corners are background, whose depth would pull the localization back).
//!
//! Masks are stored on cells of [`MASK_CELL_PX`] pixels aligned to even pixels, the grid of the
//! pipeline's label image, so each cell is sampled exactly once when the masks are painted.

use super::layout::MASK_COEFFICIENTS;
use super::letterbox::Letterbox;
use crate::detector::{DetectionMask, PixelBox};

/// Side of a mask cell, colour pixels (the pipeline's label cell).
pub const MASK_CELL_PX: u32 = 2;

/// The prototypes of one frame: `[32, height, width]`, row-major.
#[derive(Debug, Clone, Copy)]
pub struct Prototypes<'a> {
    pub data: &'a [f32],
    pub height: usize,
    pub width: usize,
}

/// An empty mask grid covering `pixel_box`, origin on an even pixel.
fn grid(pixel_box: &PixelBox) -> DetectionMask {
    let origin_u = pixel_box.u_min_px - pixel_box.u_min_px % MASK_CELL_PX;
    let origin_v = pixel_box.v_min_px - pixel_box.v_min_px % MASK_CELL_PX;
    DetectionMask::new(
        origin_u,
        origin_v,
        MASK_CELL_PX,
        (pixel_box.u_max_px - origin_u).div_ceil(MASK_CELL_PX),
        (pixel_box.v_max_px - origin_v).div_ceil(MASK_CELL_PX),
    )
}

/// Calls `f(cell_x, cell_y, u, v)` for each cell of `mask` whose centre `(u, v)` (continuous image
/// coordinates) lies in `pixel_box`.
fn for_cells_in_box(
    mask: &DetectionMask,
    pixel_box: &PixelBox,
    mut f: impl FnMut(u32, u32, f64, f64),
) {
    for cell_y in 0..mask.height_cells {
        let v_px = mask.origin_v_px + cell_y * MASK_CELL_PX + MASK_CELL_PX / 2;
        if v_px < pixel_box.v_min_px || v_px >= pixel_box.v_max_px {
            continue;
        }
        for cell_x in 0..mask.width_cells {
            let u_px = mask.origin_u_px + cell_x * MASK_CELL_PX + MASK_CELL_PX / 2;
            if u_px < pixel_box.u_min_px || u_px >= pixel_box.u_max_px {
                continue;
            }
            f(cell_x, cell_y, f64::from(u_px) + 0.5, f64::from(v_px) + 0.5);
        }
    }
}

/// The ellipse inscribed in `pixel_box` (a detect head's apple mask).
pub fn ellipse_mask(pixel_box: &PixelBox) -> DetectionMask {
    let mut mask = grid(pixel_box);
    let (cu, cv) = (
        0.5 * f64::from(pixel_box.u_min_px + pixel_box.u_max_px),
        0.5 * f64::from(pixel_box.v_min_px + pixel_box.v_max_px),
    );
    let (ru, rv) = (
        0.5 * f64::from(pixel_box.width_px()).max(1.0),
        0.5 * f64::from(pixel_box.height_px()).max(1.0),
    );
    let mut set = Vec::new();
    for_cells_in_box(&mask, pixel_box, |x, y, u, v| {
        if ((u - cu) / ru).powi(2) + ((v - cv) / rv).powi(2) <= 1.0 {
            set.push((x, y));
        }
    });
    for (x, y) in set {
        mask.set_cell(x, y, true);
    }
    mask
}

/// The segment head's mask of one detection: `coefficients` (32 values) against `protos`,
/// cropped to `pixel_box`. `scratch` holds the sigmoid of the mask on the prototype cells around
/// the box.
pub fn segment_mask(
    coefficients: &[f32; MASK_COEFFICIENTS],
    protos: &Prototypes<'_>,
    pixel_box: &PixelBox,
    letterbox: &Letterbox,
    scratch: &mut Vec<f32>,
) -> DetectionMask {
    let mut mask = grid(pixel_box);
    let plane = protos.height * protos.width;
    if protos.height == 0 || protos.width == 0 || protos.data.len() < MASK_COEFFICIENTS * plane {
        return mask;
    }
    // Input pixels per prototype cell (4 for Ultralytics' heads).
    let stride = f64::from(letterbox.input_size_px) / protos.width as f64;
    let to_proto = |u: f64, v: f64| {
        let (x, y) = letterbox.to_input(u, v);
        (x / stride - 0.5, y / stride - 0.5)
    };
    // Prototype cells the box's samples can touch (one cell of margin for the bilinear taps).
    let (x_lo, y_lo) = to_proto(f64::from(pixel_box.u_min_px), f64::from(pixel_box.v_min_px));
    let (x_hi, y_hi) = to_proto(f64::from(pixel_box.u_max_px), f64::from(pixel_box.v_max_px));
    let clamp_x = |x: f64| (x.max(0.0) as usize).min(protos.width - 1);
    let clamp_y = |y: f64| (y.max(0.0) as usize).min(protos.height - 1);
    let (x0, x1) = (clamp_x(x_lo.floor()), clamp_x(x_hi.ceil() + 1.0));
    let (y0, y1) = (clamp_y(y_lo.floor()), clamp_y(y_hi.ceil() + 1.0));
    let region_width = x1 - x0 + 1;
    scratch.clear();
    scratch.resize(region_width * (y1 - y0 + 1), 0.0);
    for y in y0..=y1 {
        for x in x0..=x1 {
            let at = y * protos.width + x;
            let logit: f32 = coefficients
                .iter()
                .enumerate()
                .map(|(k, c)| c * protos.data[k * plane + at])
                .sum();
            scratch[(y - y0) * region_width + (x - x0)] = 1.0 / (1.0 + (-logit).exp());
        }
    }
    let value = |x: usize, y: usize| scratch[(y - y0) * region_width + (x - x0)];
    let mut set = Vec::new();
    for_cells_in_box(&mask, pixel_box, |cell_x, cell_y, u, v| {
        let (px, py) = to_proto(u, v);
        let (px, py) = (
            px.clamp(x0 as f64, x1 as f64),
            py.clamp(y0 as f64, y1 as f64),
        );
        let (xa, ya) = (px.floor() as usize, py.floor() as usize);
        let (xb, yb) = ((xa + 1).min(x1), (ya + 1).min(y1));
        let (fx, fy) = ((px - xa as f64) as f32, (py - ya as f64) as f32);
        let top = value(xa, ya) + (value(xb, ya) - value(xa, ya)) * fx;
        let bottom = value(xa, yb) + (value(xb, yb) - value(xa, yb)) * fx;
        if top + (bottom - top) * fy > 0.5 {
            set.push((cell_x, cell_y));
        }
    });
    for (x, y) in set {
        mask.set_cell(x, y, true);
    }
    mask
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pixel_box(u_min_px: u32, v_min_px: u32, u_max_px: u32, v_max_px: u32) -> PixelBox {
        PixelBox {
            u_min_px,
            v_min_px,
            u_max_px,
            v_max_px,
        }
    }

    #[test]
    fn the_ellipse_fills_the_box_centre_and_leaves_its_corners() {
        let b = pixel_box(101, 40, 141, 80);
        let mask = ellipse_mask(&b);
        assert_eq!(
            (mask.origin_u_px, mask.origin_v_px, mask.cell_px),
            (100, 40, 2)
        );
        assert!(mask.contains_px(121, 60));
        assert!(!mask.contains_px(102, 41) && !mask.contains_px(139, 79));
        // A 40 px disc: pi 20^2 = 1257 px = 314 cells of 4 px.
        let cells = mask.set_cell_count() as f64;
        assert!((cells - 314.0).abs() < 15.0, "{cells}");
    }

    #[test]
    fn a_segment_mask_follows_the_prototypes_through_the_letterbox_and_stays_in_its_box() {
        // Input 32 px, prototypes 8x8 (stride 4); image 64x32 -> scale 0.5, pad top 8.
        let letterbox = Letterbox::new(64, 32, 32);
        assert_eq!((letterbox.pad_left_px, letterbox.pad_top_px), (0, 8));
        // Prototype 0 is +10 on the left half of the grid, -10 on the right; 1..32 are noise
        // that the zero coefficients ignore.
        let (height, width) = (8, 8);
        let mut data = vec![0.0f32; MASK_COEFFICIENTS * height * width];
        for y in 0..height {
            for x in 0..width {
                data[y * width + x] = if x < 4 { 10.0 } else { -10.0 };
                data[height * width + y * width + x] = 1000.0;
            }
        }
        let protos = Prototypes {
            data: &data,
            height,
            width,
        };
        let mut coefficients = [0.0f32; MASK_COEFFICIENTS];
        coefficients[0] = 1.0;
        let b = pixel_box(8, 4, 56, 28);
        let mut scratch = Vec::new();
        let mask = segment_mask(&coefficients, &protos, &b, &letterbox, &mut scratch);
        // Input x = 16 (the grid's middle) is image u = 32.
        assert!(mask.contains_px(20, 10) && mask.contains_px(30, 26));
        assert!(!mask.contains_px(34, 10) && !mask.contains_px(50, 20));
        // Cropped to the box: nothing left of u = 8 though the prototypes say apple there.
        assert!(!mask.contains_px(4, 10));
        // Left half of the box: 24 x 24 px = 144 cells.
        assert_eq!(mask.set_cell_count(), 144);
        // A negative coefficient inverts the mask.
        coefficients[0] = -1.0;
        let inverted = segment_mask(&coefficients, &protos, &b, &letterbox, &mut scratch);
        assert!(inverted.contains_px(50, 20) && !inverted.contains_px(20, 10));
    }
}
