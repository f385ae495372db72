//! Decoding of Ultralytics YOLOv8 / YOLO11 ONNX exports (detect and segment heads), pure Rust:
//! the runtime ([`crate::detector::onnx`]) hands in the output tensors, this module turns them into
//! [`Detection`]s in the full-resolution image.
//!
//! - [`layout`]: which export a model is, from its input and output shapes;
//! - [`letterbox`]: the image into the model's square input, and input pixels back to the image;
//! - [`decode`]: per-anchor best class, apple classes at or above the score threshold;
//! - [`nms`]: class-wise non-maximum suppression;
//! - [`masks`]: the segment head's masks (or the box's inscribed ellipse for a detect head).

pub mod decode;
pub mod layout;
pub mod letterbox;
pub mod masks;
pub mod nms;

use thiserror::Error;

use crate::detector::{Detection, DetectionSource, DetectorFrameInfo, PixelBox};
use crate::frame::RgbView;
use decode::Candidate;
use layout::{MASK_COEFFICIENTS, YoloHead, YoloLayout};
use letterbox::Letterbox;
use masks::Prototypes;

/// What the decoder keeps.
#[derive(Debug, Clone, PartialEq)]
pub struct DecodeSettings {
    /// Class ids that are apples.
    pub apple_classes: Vec<u32>,
    /// Minimum class score of a detection.
    pub score_threshold: f32,
    /// Class-wise NMS drops a box overlapping a better one of its class by more than this IoU.
    pub iou_threshold: f32,
    /// At most this many detections per frame.
    pub max_detections: usize,
    /// A pixel whose brightest channel reaches this is over-exposed (for the reported fractions).
    pub clip_level: u8,
}

/// Output tensors whose shapes do not match the layout identified at start.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum DecodeError {
    #[error("predictions output has shape {shape:?}, expected [1, {channels}, N]")]
    Predictions { shape: Vec<i64>, channels: usize },
    #[error("prototypes output has shape {shape:?}, expected [1, 32, H/4, W/4]")]
    Prototypes { shape: Vec<i64> },
}

/// One output tensor: its shape and data.
#[derive(Debug, Clone, Copy)]
pub struct OutputTensor<'a> {
    pub shape: &'a [i64],
    pub data: &'a [f32],
}

/// Turns the outputs of one run into detections. Holds scratch buffers; one per detector.
#[derive(Debug, Clone)]
pub struct YoloDecoder {
    layout: YoloLayout,
    settings: DecodeSettings,
    best: Vec<(f32, u32)>,
    candidates: Vec<Candidate>,
    kept: Vec<usize>,
    mask_scratch: Vec<f32>,
}

impl YoloDecoder {
    pub fn new(layout: YoloLayout, settings: DecodeSettings) -> Self {
        Self {
            layout,
            settings,
            best: Vec::new(),
            candidates: Vec::new(),
            kept: Vec::new(),
            mask_scratch: Vec::new(),
        }
    }

    pub fn layout(&self) -> &YoloLayout {
        &self.layout
    }

    /// Decodes `predictions` (and `protos` for a segment head) of a run on `rgb` letterboxed by
    /// `letterbox` into `detections` (replaced). Returns the frame information, with
    /// `candidate_regions` the candidates before NMS.
    pub fn decode(
        &mut self,
        predictions: OutputTensor<'_>,
        protos: Option<OutputTensor<'_>>,
        letterbox: &Letterbox,
        rgb: &RgbView<'_>,
        detections: &mut Vec<Detection>,
    ) -> Result<DetectorFrameInfo, DecodeError> {
        detections.clear();
        let channels = self.layout.channels();
        let anchors = match predictions.shape {
            [1, c, n] if *c == channels as i64 && *n >= 0 => *n as usize,
            _ => {
                return Err(DecodeError::Predictions {
                    shape: predictions.shape.to_vec(),
                    channels,
                });
            }
        };
        if predictions.data.len() < channels * anchors {
            return Err(DecodeError::Predictions {
                shape: predictions.shape.to_vec(),
                channels,
            });
        }
        let prototypes = match (self.layout.head, protos) {
            (YoloHead::Detect, _) => None,
            (YoloHead::Segment { .. }, Some(p)) => match p.shape {
                [1, k, h, w]
                    if *k == MASK_COEFFICIENTS as i64
                        && *h > 0
                        && *w > 0
                        && p.data.len() >= MASK_COEFFICIENTS * (*h as usize) * (*w as usize) =>
                {
                    Some(Prototypes {
                        data: p.data,
                        height: *h as usize,
                        width: *w as usize,
                    })
                }
                _ => {
                    return Err(DecodeError::Prototypes {
                        shape: p.shape.to_vec(),
                    });
                }
            },
            (YoloHead::Segment { .. }, None) => {
                return Err(DecodeError::Prototypes { shape: Vec::new() });
            }
        };
        self.candidates.clear();
        decode::candidates(
            predictions.data,
            anchors,
            self.layout.classes,
            &self.settings.apple_classes,
            self.settings.score_threshold,
            &mut self.best,
            &mut self.candidates,
        );
        nms::class_wise_nms(
            &mut self.candidates,
            self.settings.iou_threshold,
            self.settings.max_detections,
            &mut self.kept,
        );
        for &k in &self.kept {
            let candidate = self.candidates[k];
            let Some(pixel_box) = image_box(&candidate.box_input, letterbox) else {
                continue;
            };
            let mask = match &prototypes {
                None => masks::ellipse_mask(&pixel_box),
                Some(protos) => {
                    let mut coefficients = [0.0f32; MASK_COEFFICIENTS];
                    let first = 4 + self.layout.classes;
                    for (j, c) in coefficients.iter_mut().enumerate() {
                        *c = predictions.data[(first + j) * anchors + candidate.anchor];
                    }
                    masks::segment_mask(
                        &coefficients,
                        protos,
                        &pixel_box,
                        letterbox,
                        &mut self.mask_scratch,
                    )
                }
            };
            let cells = mask.set_cell_count() as u32;
            if cells == 0 {
                continue;
            }
            let saturated_fraction = clipped_fraction(&mask, rgb, self.settings.clip_level);
            detections.push(Detection {
                pixel_box,
                visible_px: cells * mask.cell_px * mask.cell_px,
                mask,
                confidence: candidate.score,
                saturated_fraction,
                source: DetectionSource::Model,
            });
        }
        Ok(DetectorFrameInfo {
            candidate_regions: self.candidates.len() as u32,
            ..DetectorFrameInfo::default()
        })
    }
}

/// The image box of an input box, clamped to the image; `None` when nothing of it is inside.
fn image_box(box_input: &[f32; 4], letterbox: &Letterbox) -> Option<PixelBox> {
    let (u1, v1) = letterbox.to_image(f64::from(box_input[0]), f64::from(box_input[1]));
    let (u2, v2) = letterbox.to_image(f64::from(box_input[2]), f64::from(box_input[3]));
    let clamp = |value: f64, max: u32| value.clamp(0.0, f64::from(max));
    let (w, h) = (letterbox.image_width_px, letterbox.image_height_px);
    let pixel_box = PixelBox {
        u_min_px: clamp(u1.floor(), w) as u32,
        v_min_px: clamp(v1.floor(), h) as u32,
        u_max_px: clamp(u2.ceil(), w) as u32,
        v_max_px: clamp(v2.ceil(), h) as u32,
    };
    (pixel_box.width_px() > 0 && pixel_box.height_px() > 0).then_some(pixel_box)
}

/// Fraction of the mask's cells whose centre pixel is over-exposed.
fn clipped_fraction(
    mask: &crate::detector::DetectionMask,
    rgb: &RgbView<'_>,
    clip_level: u8,
) -> f32 {
    let (mut set, mut clipped) = (0u32, 0u32);
    for cell_y in 0..mask.height_cells {
        let v = mask.origin_v_px + cell_y * mask.cell_px + mask.cell_px / 2;
        for cell_x in 0..mask.width_cells {
            if !mask.cell(cell_x, cell_y) {
                continue;
            }
            let u = mask.origin_u_px + cell_x * mask.cell_px + mask.cell_px / 2;
            let at = (v as usize * rgb.width_px as usize + u as usize) * 3;
            set += 1;
            if let Some(pixel) = rgb.data.get(at..at + 3) {
                clipped += u32::from(pixel.iter().any(|&c| c >= clip_level));
            }
        }
    }
    if set == 0 {
        0.0
    } else {
        clipped as f32 / set as f32
    }
}

#[cfg(test)]
mod tests;
