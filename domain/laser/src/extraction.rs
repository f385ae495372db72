//! Laser-line extraction: one sub-pixel stripe position per image row ([alacs sec. 3],
//! "refinement of 3D position"; the paper defers the details to its ref. 44, so this is our
//! design).
//!
//! Per row of the region of interest:
//! 1. **Red top-hat.** The red channel minus its morphological opening with a window a little
//!    wider than the stripe. A narrow bright red ridge survives; broad red (the apple itself),
//!    shading gradients and silhouette steps do not.
//! 2. **Peaks.** Runs of the top-hat above `min_peak_contrast_dn`; each run's maximum is a
//!    candidate, kept only if the red value there is laser-bright (`min_peak_red_dn`).
//! 3. **Leaf rejection.** The surface colour just outside the stripe on both sides is
//!    inspected; a stripe with a leaf-green flank is dropped (the laser on a leaf, or an apple
//!    edge half hidden by one).
//! 4. **Clear peak.** If another surviving peak reaches `ambiguity_ratio` of the best, the row
//!    is rejected: two stripes in one row mean occlusion or reflections we cannot resolve.
//! 5. **Sub-pixel centre.** Centroid of the top-hat above half its maximum over the peak's run.
//!    On a saturated (flat-topped) stripe this is the plateau's centre.

use serde::{Deserialize, Serialize};

/// Tunables of [`LaserLineExtractor`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExtractionConfig {
    /// Opening window of the top-hat, pixels (odd; wider than the stripe's full width).
    pub opening_window_px: usize,
    /// Smallest top-hat value at a stripe's peak, digital numbers.
    pub min_peak_contrast_dn: f64,
    /// Smallest red value at a stripe's peak, digital numbers.
    pub min_peak_red_dn: f64,
    /// A second peak reaching this share of the best one makes the row ambiguous.
    pub ambiguity_ratio: f64,
    /// A flank is leaf-green when its green exceeds this multiple of both red and blue.
    pub leaf_green_ratio: f64,
}

impl Default for ExtractionConfig {
    fn default() -> Self {
        Self {
            opening_window_px: 15,
            min_peak_contrast_dn: 35.0,
            min_peak_red_dn: 120.0,
            ambiguity_ratio: 0.6,
            leaf_green_ratio: 1.3,
        }
    }
}

/// A rectangle of pixels, `min` inclusive, `max` exclusive.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PixelRoi {
    pub u_min_px: usize,
    pub v_min_px: usize,
    pub u_max_px: usize,
    pub v_max_px: usize,
}

impl PixelRoi {
    /// The whole image.
    pub fn full(width_px: usize, height_px: usize) -> Self {
        Self {
            u_min_px: 0,
            v_min_px: 0,
            u_max_px: width_px,
            v_max_px: height_px,
        }
    }

    /// This rectangle clipped to a `width x height` image.
    pub fn clipped(&self, width_px: usize, height_px: usize) -> Self {
        Self {
            u_min_px: self.u_min_px.min(width_px),
            v_min_px: self.v_min_px.min(height_px),
            u_max_px: self.u_max_px.min(width_px),
            v_max_px: self.v_max_px.min(height_px),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.u_min_px >= self.u_max_px || self.v_min_px >= self.v_max_px
    }
}

/// The stripe centre found in one row.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct StripePoint {
    /// Sub-pixel column of the stripe centre.
    pub u_px: f64,
    /// Row (pixel centre).
    pub v_px: f64,
    /// Top-hat height at the peak, digital numbers.
    pub contrast_dn: f64,
}

/// How many rows were kept and why the others were not.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct ExtractionStats {
    pub rows: usize,
    pub rows_with_stripe: usize,
    pub rows_without_peak: usize,
    pub rows_ambiguous: usize,
    pub peaks_on_leaves: usize,
}

/// Why an image could not be processed at all.
#[derive(Debug, Clone, thiserror::Error, PartialEq)]
pub enum ExtractionError {
    /// The buffer is not `width x height x 3` bytes.
    #[error("RGB buffer holds {got_bytes} bytes, {width_px}x{height_px} RGB needs {needed_bytes}")]
    BufferSize {
        got_bytes: usize,
        needed_bytes: usize,
        width_px: usize,
        height_px: usize,
    },
    /// The region of interest does not overlap the image.
    #[error("region of interest {roi:?} is empty inside a {width_px}x{height_px} image")]
    EmptyRoi {
        roi: PixelRoi,
        width_px: usize,
        height_px: usize,
    },
    /// A configuration value is unusable.
    #[error("extraction config {name} = {value} is invalid")]
    InvalidConfig { name: &'static str, value: f64 },
}

/// Extracts the laser stripe from RGB8 images; keeps its scratch buffers between images so the
/// per-image work allocates nothing once warm.
#[derive(Debug, Clone, Default)]
pub struct LaserLineExtractor {
    config: ExtractionConfig,
    red: Vec<f64>,
    eroded: Vec<f64>,
    top_hat: Vec<f64>,
    peaks: Vec<Peak>,
    points: Vec<StripePoint>,
    stats: ExtractionStats,
}

#[derive(Debug, Clone, Copy)]
struct Peak {
    /// Column of the maximum, relative to the ROI.
    argmax: usize,
    /// Run of top-hat values above the contrast threshold, relative to the ROI, inclusive.
    run_start: usize,
    run_end: usize,
    contrast_dn: f64,
}

impl LaserLineExtractor {
    pub fn new(config: ExtractionConfig) -> Result<Self, ExtractionError> {
        let checks = [
            (
                "opening_window_px",
                config.opening_window_px as f64,
                config.opening_window_px >= 3,
            ),
            (
                "min_peak_contrast_dn",
                config.min_peak_contrast_dn,
                config.min_peak_contrast_dn > 0.0,
            ),
            (
                "min_peak_red_dn",
                config.min_peak_red_dn,
                config.min_peak_red_dn.is_finite(),
            ),
            (
                "ambiguity_ratio",
                config.ambiguity_ratio,
                config.ambiguity_ratio > 0.0 && config.ambiguity_ratio <= 1.0,
            ),
            (
                "leaf_green_ratio",
                config.leaf_green_ratio,
                config.leaf_green_ratio >= 1.0,
            ),
        ];
        for (name, value, valid) in checks {
            if !valid || !value.is_finite() {
                return Err(ExtractionError::InvalidConfig { name, value });
            }
        }
        Ok(Self {
            config,
            ..Self::default()
        })
    }

    pub fn config(&self) -> &ExtractionConfig {
        &self.config
    }

    /// Statistics of the last [`Self::extract`] call.
    pub fn stats(&self) -> ExtractionStats {
        self.stats
    }

    /// Finds the stripe in every row of `roi` (clipped to the image) of the row-major RGB8
    /// image `rgb`. Returns the kept rows' stripe centres, top to bottom.
    pub fn extract(
        &mut self,
        rgb: &[u8],
        width_px: usize,
        height_px: usize,
        roi: PixelRoi,
    ) -> Result<&[StripePoint], ExtractionError> {
        let needed_bytes = width_px * height_px * 3;
        if rgb.len() != needed_bytes {
            return Err(ExtractionError::BufferSize {
                got_bytes: rgb.len(),
                needed_bytes,
                width_px,
                height_px,
            });
        }
        let clipped = roi.clipped(width_px, height_px);
        if clipped.is_empty() {
            return Err(ExtractionError::EmptyRoi {
                roi,
                width_px,
                height_px,
            });
        }
        self.points.clear();
        self.stats = ExtractionStats::default();
        let roi_width = clipped.u_max_px - clipped.u_min_px;
        self.red.resize(roi_width, 0.0);
        self.eroded.resize(roi_width, 0.0);
        self.top_hat.resize(roi_width, 0.0);
        for v in clipped.v_min_px..clipped.v_max_px {
            let row = &rgb[v * width_px * 3..(v + 1) * width_px * 3];
            self.stats.rows += 1;
            if let Some(point) = self.extract_row(row, v, clipped) {
                self.stats.rows_with_stripe += 1;
                self.points.push(point);
            }
        }
        tracing::trace!(stats = ?self.stats, "laser line extracted");
        Ok(&self.points)
    }

    fn extract_row(&mut self, row: &[u8], v: usize, roi: PixelRoi) -> Option<StripePoint> {
        let config = self.config;
        let half_window = config.opening_window_px / 2;
        for (k, red) in self.red.iter_mut().enumerate() {
            *red = f64::from(row[(roi.u_min_px + k) * 3]);
        }
        // Opening = dilation of the erosion; the top-hat keeps what is narrower than the window.
        sliding_extreme(&self.red, half_window, f64::min, &mut self.eroded);
        sliding_extreme(&self.eroded, half_window, f64::max, &mut self.top_hat);
        for (top_hat, red) in self.top_hat.iter_mut().zip(&self.red) {
            *top_hat = red - *top_hat;
        }

        self.peaks.clear();
        let mut k = 0;
        while k < self.top_hat.len() {
            if self.top_hat[k] < config.min_peak_contrast_dn {
                k += 1;
                continue;
            }
            let run_start = k;
            let mut argmax = k;
            while k < self.top_hat.len() && self.top_hat[k] >= config.min_peak_contrast_dn {
                if self.top_hat[k] > self.top_hat[argmax] {
                    argmax = k;
                }
                k += 1;
            }
            self.peaks.push(Peak {
                argmax,
                run_start,
                run_end: k - 1,
                contrast_dn: self.top_hat[argmax],
            });
        }
        if self.peaks.is_empty() {
            self.stats.rows_without_peak += 1;
            return None;
        }

        let mut best: Option<Peak> = None;
        let mut runner_up_dn = 0.0_f64;
        for peak in &self.peaks {
            if self.red[peak.argmax] < config.min_peak_red_dn {
                continue;
            }
            if flank_is_leaf(row, roi, peak, half_window, config.leaf_green_ratio) {
                self.stats.peaks_on_leaves += 1;
                continue;
            }
            match best {
                Some(current) if current.contrast_dn >= peak.contrast_dn => {
                    runner_up_dn = runner_up_dn.max(peak.contrast_dn);
                }
                Some(current) => {
                    runner_up_dn = runner_up_dn.max(current.contrast_dn);
                    best = Some(*peak);
                }
                None => best = Some(*peak),
            }
        }
        let Some(best) = best else {
            self.stats.rows_without_peak += 1;
            return None;
        };
        if runner_up_dn >= config.ambiguity_ratio * best.contrast_dn {
            self.stats.rows_ambiguous += 1;
            return None;
        }

        // Centroid above half maximum, over the contiguous part of the run around the maximum.
        let half_dn = 0.5 * best.contrast_dn;
        let mut first = best.argmax;
        while first > best.run_start && self.top_hat[first - 1] >= half_dn {
            first -= 1;
        }
        let mut last = best.argmax;
        while last < best.run_end && self.top_hat[last + 1] >= half_dn {
            last += 1;
        }
        let (mut weight_sum, mut moment) = (0.0, 0.0);
        for (k, top_hat) in self.top_hat.iter().enumerate().take(last + 1).skip(first) {
            let weight = top_hat - half_dn;
            weight_sum += weight;
            moment += weight * k as f64;
        }
        let centre = if weight_sum > 0.0 {
            moment / weight_sum
        } else {
            best.argmax as f64
        };
        Some(StripePoint {
            u_px: roi.u_min_px as f64 + centre,
            v_px: v as f64,
            contrast_dn: best.contrast_dn,
        })
    }
}

/// `output[k] = extreme(input[k - half ..= k + half])`, window clipped at the ends.
fn sliding_extreme(input: &[f64], half: usize, extreme: fn(f64, f64) -> f64, output: &mut [f64]) {
    for (k, out) in output.iter_mut().enumerate() {
        let first = k.saturating_sub(half);
        let last = (k + half).min(input.len() - 1);
        *out = input[first..=last].iter().copied().fold(input[k], extreme);
    }
}

/// True when the surface just outside the stripe (either side) is leaf green.
fn flank_is_leaf(row: &[u8], roi: PixelRoi, peak: &Peak, half_window: usize, ratio: f64) -> bool {
    let centre = roi.u_min_px + peak.argmax;
    let offset = half_window + 1;
    let sides = [
        centre.checked_sub(offset).filter(|u| *u >= roi.u_min_px),
        Some(centre + offset).filter(|u| *u < roi.u_max_px),
    ];
    sides.into_iter().flatten().any(|u| {
        let [red, green, blue] = [row[u * 3], row[u * 3 + 1], row[u * 3 + 2]].map(f64::from);
        green > ratio * red.max(blue) && green >= 20.0
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A synthetic image: red apple disc-free rows, background, a Gaussian stripe at `centre`.
    fn image_with_stripe(
        width: usize,
        height: usize,
        centre_of_row: impl Fn(usize) -> f64,
    ) -> Vec<u8> {
        let mut rgb = vec![0; width * height * 3];
        for v in 0..height {
            let centre = centre_of_row(v);
            for u in 0..width {
                let offset = u as f64 - centre;
                let laser = (-offset * offset / (2.0 * 1.5 * 1.5)).exp();
                let base = if u < width / 2 {
                    [140.0, 30.0, 25.0]
                } else {
                    [70.0, 75.0, 60.0]
                };
                let pixel = &mut rgb[(v * width + u) * 3..(v * width + u) * 3 + 3];
                for channel in 0..3 {
                    let gain = [200.0, 60.0, 45.0][channel];
                    pixel[channel] = (base[channel] + laser * gain).round().clamp(0.0, 255.0) as u8;
                }
            }
        }
        rgb
    }

    #[test]
    fn finds_the_sub_pixel_centre_even_when_saturated() {
        let (width, height) = (120, 20);
        let centre_of_row = |v: usize| 30.0 + 0.37 * v as f64;
        let rgb = image_with_stripe(width, height, centre_of_row);
        let mut extractor = LaserLineExtractor::new(ExtractionConfig::default()).expect("config");
        let points = extractor
            .extract(&rgb, width, height, PixelRoi::full(width, height))
            .expect("extract")
            .to_vec();
        assert_eq!(points.len(), height);
        for point in points {
            let truth = centre_of_row(point.v_px as usize);
            assert!((point.u_px - truth).abs() < 0.15, "{point:?} vs {truth}");
        }
    }

    #[test]
    fn stripes_on_green_leaves_and_double_stripes_are_rejected() {
        let (width, height) = (120, 3);
        let mut rgb = image_with_stripe(width, height, |_| 30.0);
        // Row 1: the stripe lies on a green leaf.
        for u in 15..45 {
            let pixel = &mut rgb[(width + u) * 3..(width + u) * 3 + 3];
            let lift = f64::from(pixel[0]) - 140.0;
            pixel.copy_from_slice(&[(40.0 + lift) as u8, 110, 35]);
        }
        // Row 2: a second equally strong stripe at column 90.
        for u in 85..96 {
            let offset = u as f64 - 90.0;
            let laser = (-offset * offset / 4.5).exp();
            rgb[(2 * width + u) * 3] = (70.0 + 120.0 * laser).min(255.0) as u8;
        }
        let mut extractor = LaserLineExtractor::new(ExtractionConfig::default()).expect("config");
        let rows: Vec<f64> = extractor
            .extract(&rgb, width, height, PixelRoi::full(width, height))
            .expect("extract")
            .iter()
            .map(|p| p.v_px)
            .collect();
        assert_eq!(rows, vec![0.0]);
        let stats = extractor.stats();
        assert_eq!(stats.peaks_on_leaves, 1);
        assert_eq!(stats.rows_ambiguous, 1);
    }

    #[test]
    fn rows_without_laser_give_nothing_and_bad_buffers_are_refused() {
        let (width, height) = (50, 4);
        let rgb = vec![120; width * height * 3];
        let mut extractor = LaserLineExtractor::new(ExtractionConfig::default()).expect("config");
        assert!(
            extractor
                .extract(&rgb, width, height, PixelRoi::full(width, height))
                .expect("ok")
                .is_empty()
        );
        assert!(matches!(
            extractor.extract(&rgb[1..], width, height, PixelRoi::full(width, height)),
            Err(ExtractionError::BufferSize { .. })
        ));
        let outside = PixelRoi {
            u_min_px: 60,
            v_min_px: 0,
            u_max_px: 70,
            v_max_px: 4,
        };
        assert!(matches!(
            extractor.extract(&rgb, width, height, outside),
            Err(ExtractionError::EmptyRoi { .. })
        ));
        assert!(
            LaserLineExtractor::new(ExtractionConfig {
                ambiguity_ratio: f64::NAN,
                ..ExtractionConfig::default()
            })
            .is_err()
        );
    }
}
