//! Which YOLO export a model is, from the shapes of its inputs and outputs.
//!
//! Ultralytics' YOLOv8 / YOLO11 ONNX exports (`format=onnx`, no `nms=True`, no `end2end`):
//! - input: one float tensor `[1, 3, H, W]` (RGB, 0-1, letterboxed);
//! - detect: one output `[1, 4 + nc, N]`: per anchor `cx, cy, w, h` in input pixels, then the
//!   `nc` class scores (already sigmoided, no objectness);
//! - segment: `[1, 4 + nc + 32, N]` (the same, then 32 mask coefficients) and the prototypes
//!   `[1, 32, H/4, W/4]`.
//!
//! `N` is the number of anchors, `(H/8)(W/8) + (H/16)(W/16) + (H/32)(W/32)` (8400 at 640). Any
//! dimension may be dynamic (`-1` here) in the file; it is then taken from the run.
//! Anything else (a transposed `[1, N, 4 + nc]` head, an end-to-end `[1, 300, 6]` head with NMS
//! inside, several inputs, integer inputs) is refused at start with the shapes found and expected.

use std::fmt;

use thiserror::Error;

/// Number of mask coefficients (and prototype channels) of a YOLO segmentation head.
pub const MASK_COEFFICIENTS: usize = 32;

/// Element type of a model tensor, as far as layout checks need it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ElementType {
    Float32,
    /// Any other element type (named for the error message).
    Other(&'static str),
}

/// Name, element type and shape of one model input or output; `-1` marks a dynamic dimension.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TensorInfo {
    pub name: String,
    pub element: ElementType,
    pub shape: Vec<i64>,
}

impl fmt::Display for TensorInfo {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} [", self.name)?;
        for (k, dim) in self.shape.iter().enumerate() {
            if k > 0 {
                write!(f, ", ")?;
            }
            if *dim < 0 {
                write!(f, "?")?;
            } else {
                write!(f, "{dim}")?;
            }
        }
        match self.element {
            ElementType::Float32 => write!(f, "] f32"),
            ElementType::Other(name) => write!(f, "] {name}"),
        }
    }
}

/// The head of a recognised export.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum YoloHead {
    /// Boxes and class scores only.
    Detect,
    /// Boxes, class scores and mask coefficients, plus prototypes (output `protos_output`).
    Segment { protos_output: usize },
}

/// A model recognised as a YOLO export.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct YoloLayout {
    pub head: YoloHead,
    /// Number of classes `nc`.
    pub classes: usize,
    /// Side of the square input the model is run at, pixels.
    pub input_size_px: u32,
    /// Index of the `[1, 4 + nc (+ 32), N]` output.
    pub predictions_output: usize,
}

/// What the layouts expect, for error messages.
pub const EXPECTED_LAYOUTS: &str = "one float input [1, 3, H, W] and either detect: one output \
     [1, 4+nc, N] or segment: outputs [1, 4+nc+32, N] and [1, 32, H/4, W/4] (Ultralytics \
     YOLOv8/YOLO11 ONNX export without nms/end2end)";

/// A model that fits no known layout, or does not fit the configuration.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum LayoutError {
    /// The inputs and outputs fit neither the detect nor the segment layout.
    #[error("model has inputs [{inputs}] and outputs [{outputs}]: {reason}; expected {EXPECTED_LAYOUTS}", inputs = join(.inputs), outputs = join(.outputs))]
    Unknown {
        inputs: Vec<TensorInfo>,
        outputs: Vec<TensorInfo>,
        reason: String,
    },
    /// The model's fixed input size differs from the configured `input_size`.
    #[error("model input {input} is fixed at {model_px} px but input_size = {configured_px}")]
    InputSize {
        input: TensorInfo,
        model_px: i64,
        configured_px: u32,
    },
    /// A configured apple class id is not one of the model's classes.
    #[error(
        "classes = {class_id} is not a class of this model (it has {classes}: ids 0..{classes})"
    )]
    ClassId { class_id: u32, classes: usize },
}

fn join(tensors: &[TensorInfo]) -> String {
    tensors
        .iter()
        .map(ToString::to_string)
        .collect::<Vec<_>>()
        .join(", ")
}

/// Identifies the export from the model's inputs and outputs. `input_size_px` is the configured
/// input side: a fixed model input must equal it (a model exported at 640 runs at 640), a dynamic
/// one takes it.
pub fn identify(
    inputs: &[TensorInfo],
    outputs: &[TensorInfo],
    input_size_px: u32,
) -> Result<YoloLayout, LayoutError> {
    let unknown = |reason: &str| LayoutError::Unknown {
        inputs: inputs.to_vec(),
        outputs: outputs.to_vec(),
        reason: reason.to_string(),
    };
    let [input] = inputs else {
        return Err(unknown("not exactly one input"));
    };
    let fits = |dim: i64, value: i64| dim < 0 || dim == value;
    let input_ok = input.element == ElementType::Float32
        && input.shape.len() == 4
        && fits(input.shape[0], 1)
        && fits(input.shape[1], 3);
    if !input_ok {
        return Err(unknown("the input is not a float [1, 3, H, W] image"));
    }
    let (height, width) = (input.shape[2], input.shape[3]);
    if height >= 0 && width >= 0 && height != width {
        return Err(unknown("the input is not square"));
    }
    for side in [height, width] {
        if side >= 0 && side != i64::from(input_size_px) {
            return Err(LayoutError::InputSize {
                input: input.clone(),
                model_px: side,
                configured_px: input_size_px,
            });
        }
    }
    let size = i64::from(input_size_px);
    let is_predictions = |t: &TensorInfo| {
        t.element == ElementType::Float32
            && t.shape.len() == 3
            && fits(t.shape[0], 1)
            && t.shape[1] > 4
            && fits(t.shape[2], expected_anchors(input_size_px) as i64)
    };
    let is_protos = |t: &TensorInfo| {
        t.element == ElementType::Float32
            && t.shape.len() == 4
            && fits(t.shape[0], 1)
            && t.shape[1] == MASK_COEFFICIENTS as i64
            && fits(t.shape[2], size / 4)
            && fits(t.shape[3], size / 4)
    };
    match outputs {
        [predictions] if is_predictions(predictions) => Ok(YoloLayout {
            head: YoloHead::Detect,
            classes: (predictions.shape[1] - 4) as usize,
            input_size_px,
            predictions_output: 0,
        }),
        [a, b] => {
            let (predictions_output, protos_output) = if is_predictions(a) && is_protos(b) {
                (0, 1)
            } else if is_predictions(b) && is_protos(a) {
                (1, 0)
            } else {
                return Err(unknown(
                    "two outputs, but not predictions [1, 4+nc+32, N] and prototypes [1, 32, H/4, W/4]",
                ));
            };
            let channels = outputs[predictions_output].shape[1];
            let classes = channels - 4 - MASK_COEFFICIENTS as i64;
            if classes < 1 {
                return Err(unknown(
                    "the predictions have too few channels for 4 box values, a class and 32 mask coefficients",
                ));
            }
            Ok(YoloLayout {
                head: YoloHead::Segment { protos_output },
                classes: classes as usize,
                input_size_px,
                predictions_output,
            })
        }
        [_] => Err(unknown(
            "the output is not [1, 4+nc, N] with N the anchors of the input size",
        )),
        _ => Err(unknown("neither one nor two outputs")),
    }
}

/// Anchors of a YOLOv8/11 head (strides 8, 16, 32) on a square input of `size_px`.
pub fn expected_anchors(size_px: u32) -> usize {
    [8, 16, 32]
        .iter()
        .map(|stride| (size_px as usize / stride).pow(2))
        .sum()
}

impl YoloLayout {
    /// Checks the configured apple class ids against the model's classes.
    pub fn check_classes(&self, class_ids: &[u32]) -> Result<(), LayoutError> {
        match class_ids.iter().find(|&&id| id as usize >= self.classes) {
            Some(&class_id) => Err(LayoutError::ClassId {
                class_id,
                classes: self.classes,
            }),
            None => Ok(()),
        }
    }

    /// Channels per anchor in the predictions output.
    pub fn channels(&self) -> usize {
        match self.head {
            YoloHead::Detect => 4 + self.classes,
            YoloHead::Segment { .. } => 4 + self.classes + MASK_COEFFICIENTS,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tensor(name: &str, shape: &[i64]) -> TensorInfo {
        TensorInfo {
            name: name.to_string(),
            element: ElementType::Float32,
            shape: shape.to_vec(),
        }
    }

    #[test]
    fn yolo11n_detect_and_segment_exports_are_recognised() {
        assert_eq!(expected_anchors(640), 8400);
        let input = [tensor("images", &[1, 3, 640, 640])];
        let detect = identify(&input, &[tensor("output0", &[1, 84, 8400])], 640).expect("detect");
        assert_eq!(detect.head, YoloHead::Detect);
        assert_eq!(detect.classes, 80);
        let segment = identify(
            &input,
            &[
                tensor("output0", &[1, 116, 8400]),
                tensor("output1", &[1, 32, 160, 160]),
            ],
            640,
        )
        .expect("segment");
        assert_eq!(segment.head, YoloHead::Segment { protos_output: 1 });
        assert_eq!((segment.classes, segment.channels()), (80, 116));
        // Dynamic axes take the configured size.
        let dynamic = identify(
            &[tensor("images", &[-1, 3, -1, -1])],
            &[
                tensor("output1", &[-1, 32, -1, -1]),
                tensor("output0", &[-1, 37, -1]),
            ],
            320,
        )
        .expect("dynamic segment");
        assert_eq!(dynamic.head, YoloHead::Segment { protos_output: 0 });
        assert_eq!((dynamic.classes, dynamic.predictions_output), (1, 1));
    }

    #[test]
    fn other_layouts_are_refused_with_the_shapes_found_and_expected() {
        let input = [tensor("images", &[1, 3, 640, 640])];
        let end2end = identify(&input, &[tensor("output0", &[1, 300, 6])], 640)
            .expect_err("end2end head")
            .to_string();
        assert!(
            end2end.contains("images [1, 3, 640, 640] f32")
                && end2end.contains("output0 [1, 300, 6] f32")
                && end2end.contains("[1, 4+nc, N]")
                && end2end.contains("[1, 32, H/4, W/4]"),
            "{end2end}"
        );
        let transposed = identify(&input, &[tensor("output0", &[1, 8400, 84])], 640);
        assert!(matches!(transposed, Err(LayoutError::Unknown { .. })));
        let integer_input = TensorInfo {
            element: ElementType::Other("u8"),
            ..tensor("images", &[1, 3, 640, 640])
        };
        let message = identify(&[integer_input], &[tensor("output0", &[1, 84, 8400])], 640)
            .expect_err("u8 input")
            .to_string();
        assert!(message.contains("images [1, 3, 640, 640] u8"), "{message}");
        let size = identify(&input, &[tensor("output0", &[1, 84, 8400])], 320)
            .expect_err("fixed 640 run at 320")
            .to_string();
        assert!(
            size.contains("640") && size.contains("input_size = 320"),
            "{size}"
        );
        let layout = identify(&input, &[tensor("output0", &[1, 5, 8400])], 640).expect("1 class");
        assert!(layout.check_classes(&[0]).is_ok());
        let class = layout
            .check_classes(&[0, 47])
            .expect_err("class 47")
            .to_string();
        assert!(class.contains("47") && class.contains("1"), "{class}");
    }
}
