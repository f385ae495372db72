//! The letterbox a YOLO export expects: the image scaled to fit a square input, keeping its aspect
//! ratio, centred, the rest padded with grey 114; and the way back from input to image pixels.
//!
//! The same arithmetic as Ultralytics' `LetterBox` (scale `r = min(S/W, S/H)`, resized size
//! `round(W r) x round(H r)`, left/top padding `round(pad/2 - 0.1)`, bilinear resampling with
//! OpenCV's half-pixel convention) and `scale_boxes` (subtract the padding, divide by `r`).

use crate::frame::RgbView;

/// Grey level of the padding, as Ultralytics pads (0-255).
pub const PAD_LEVEL: u8 = 114;

/// The letterbox of one image size onto one square input size.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Letterbox {
    pub image_width_px: u32,
    pub image_height_px: u32,
    /// Side of the square input, pixels.
    pub input_size_px: u32,
    /// Input pixels per image pixel.
    pub scale: f64,
    /// Size of the resized image inside the input.
    pub resized_width_px: u32,
    pub resized_height_px: u32,
    /// Padding left of and above the resized image, input pixels.
    pub pad_left_px: u32,
    pub pad_top_px: u32,
}

impl Letterbox {
    /// The letterbox of a `width_px x height_px` image (both > 0) onto a `size_px` square.
    pub fn new(width_px: u32, height_px: u32, size_px: u32) -> Self {
        let (w, h, s) = (
            f64::from(width_px.max(1)),
            f64::from(height_px.max(1)),
            f64::from(size_px),
        );
        let scale = (s / w).min(s / h);
        let resized_width_px = ((w * scale).round() as u32).clamp(1, size_px);
        let resized_height_px = ((h * scale).round() as u32).clamp(1, size_px);
        let pad = |resized: u32| {
            let half = f64::from(size_px - resized) / 2.0;
            (half - 0.1).round().max(0.0) as u32
        };
        Self {
            image_width_px: width_px,
            image_height_px: height_px,
            input_size_px: size_px,
            scale,
            resized_width_px,
            resized_height_px,
            pad_left_px: pad(resized_width_px),
            pad_top_px: pad(resized_height_px),
        }
    }

    /// Image coordinates (continuous, pixel `u` spans `[u, u + 1)`) of input coordinates.
    pub fn to_image(&self, x_input: f64, y_input: f64) -> (f64, f64) {
        (
            (x_input - f64::from(self.pad_left_px)) / self.scale,
            (y_input - f64::from(self.pad_top_px)) / self.scale,
        )
    }

    /// Input coordinates (continuous) of image coordinates.
    pub fn to_input(&self, u_image: f64, v_image: f64) -> (f64, f64) {
        (
            u_image * self.scale + f64::from(self.pad_left_px),
            v_image * self.scale + f64::from(self.pad_top_px),
        )
    }

    /// Writes the letterboxed image into `input` as a `[1, 3, S, S]` float tensor (RGB planes,
    /// values 0-1), resizing `input` as needed. `rgb` must hold `image_width_px x
    /// image_height_px` pixels (checked by the caller). Returns the fraction of the sampled image
    /// pixels whose brightest channel reaches `clip_level` (the frame's over-exposure).
    pub fn fill_input(&self, rgb: &RgbView<'_>, input: &mut Vec<f32>, clip_level: u8) -> f32 {
        let size = self.input_size_px as usize;
        let plane = size * size;
        input.clear();
        input.resize(3 * plane, f32::from(PAD_LEVEL) / 255.0);
        let (width, height) = (rgb.width_px as usize, rgb.height_px as usize);
        if width == 0 || height == 0 || rgb.data.len() < width * height * 3 {
            return 0.0;
        }
        // OpenCV INTER_LINEAR: source = (destination + 0.5) * (source size / resized size) - 0.5.
        // Each tap: the two source pixels, the weight of the second, the nearest source pixel.
        let taps = |resized: u32, source: usize| -> Vec<(usize, usize, f32, usize)> {
            let ratio = source as f64 / f64::from(resized);
            (0..resized)
                .map(|d| {
                    let s = ((f64::from(d) + 0.5) * ratio - 0.5).max(0.0);
                    let s0 = (s.floor() as usize).min(source - 1);
                    let s1 = (s0 + 1).min(source - 1);
                    let nearest = (s.round() as usize).min(source - 1);
                    (s0, s1, (s - s0 as f64) as f32, nearest)
                })
                .collect()
        };
        let columns = taps(self.resized_width_px, width);
        let rows = taps(self.resized_height_px, height);
        let (left, top) = (self.pad_left_px as usize, self.pad_top_px as usize);
        let mut clipped = 0u64;
        let mut sampled = 0u64;
        let pixel = |x: usize, y: usize| {
            let at = (y * width + x) * 3;
            [rgb.data[at], rgb.data[at + 1], rgb.data[at + 2]]
        };
        for (dy, &(y0, y1, fy, y_nearest)) in rows.iter().enumerate() {
            let out_row = (top + dy) * size + left;
            for (dx, &(x0, x1, fx, x_nearest)) in columns.iter().enumerate() {
                let (a, b, c, d) = (pixel(x0, y0), pixel(x1, y0), pixel(x0, y1), pixel(x1, y1));
                sampled += 1;
                clipped += u64::from(
                    pixel(x_nearest, y_nearest)
                        .iter()
                        .any(|&channel| channel >= clip_level),
                );
                for channel in 0..3 {
                    let top_value = f32::from(a[channel])
                        + (f32::from(b[channel]) - f32::from(a[channel])) * fx;
                    let bottom_value = f32::from(c[channel])
                        + (f32::from(d[channel]) - f32::from(c[channel])) * fx;
                    let value = top_value + (bottom_value - top_value) * fy;
                    input[channel * plane + out_row + dx] = value / 255.0;
                }
            }
        }
        if sampled == 0 {
            0.0
        } else {
            clipped as f32 / sampled as f32
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_wide_frame_is_scaled_to_the_width_and_padded_above_and_below() {
        let letterbox = Letterbox::new(1920, 1080, 640);
        assert!((letterbox.scale - 1.0 / 3.0).abs() < 1e-12);
        assert_eq!(
            (letterbox.resized_width_px, letterbox.resized_height_px),
            (640, 360)
        );
        assert_eq!((letterbox.pad_left_px, letterbox.pad_top_px), (0, 140));
        let (u, v) = letterbox.to_image(320.0, 320.0);
        assert!((u - 960.0).abs() < 1e-9 && (v - 540.0).abs() < 1e-9);
        let (x, y) = letterbox.to_input(u, v);
        assert!((x - 320.0).abs() < 1e-9 && (y - 320.0).abs() < 1e-9);
        // Odd padding: 640 - 427 = 213, left = round(106.5 - 0.1) = 106.
        let odd = Letterbox::new(1000, 1500, 640);
        assert_eq!(
            (odd.resized_width_px, odd.pad_left_px, odd.pad_top_px),
            (427, 106, 0)
        );
    }

    #[test]
    fn the_input_holds_the_resampled_image_inside_grey_padding() {
        // A 4x2 image: left half red, right half clipped white; letterboxed onto 8x8.
        let mut data = Vec::new();
        for _ in 0..2 {
            for x in 0..4 {
                data.extend_from_slice(if x < 2 {
                    &[200, 0, 0]
                } else {
                    &[255, 255, 255]
                });
            }
        }
        let rgb = RgbView {
            width_px: 4,
            height_px: 2,
            data: &data,
        };
        let letterbox = Letterbox::new(4, 2, 8);
        assert_eq!(
            (letterbox.resized_width_px, letterbox.resized_height_px),
            (8, 4)
        );
        assert_eq!(letterbox.pad_top_px, 2);
        let mut input = Vec::new();
        let clipped = letterbox.fill_input(&rgb, &mut input, 250);
        assert_eq!(input.len(), 3 * 64);
        assert!((clipped - 0.5).abs() < 1e-6, "{clipped}");
        let at = |channel: usize, x: usize, y: usize| input[channel * 64 + y * 8 + x];
        let grey = 114.0 / 255.0;
        assert!((at(0, 0, 0) - grey).abs() < 1e-6 && (at(2, 7, 7) - grey).abs() < 1e-6);
        assert!((at(0, 0, 2) - 200.0 / 255.0).abs() < 1e-6);
        assert!(at(1, 0, 3).abs() < 1e-6);
        assert!((at(1, 7, 5) - 1.0).abs() < 1e-6);
        // Column 3 samples source x = 1.25: a quarter of the way to white.
        let expected = (200.0 + 0.25 * 55.0) / 255.0;
        assert!((at(0, 3, 2) - expected).abs() < 1e-5, "{}", at(0, 3, 2));
    }
}
