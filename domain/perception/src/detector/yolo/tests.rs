//! The decoder end to end on hand-made output tensors.

use super::*;

/// `[channels, anchors]` row-major from per-anchor rows.
fn tensor(rows: &[Vec<f32>]) -> Vec<f32> {
    let channels = rows[0].len();
    let mut data = vec![0.0; channels * rows.len()];
    for (anchor, row) in rows.iter().enumerate() {
        for (channel, &value) in row.iter().enumerate() {
            data[channel * rows.len() + anchor] = value;
        }
    }
    data
}

fn settings(apple_classes: &[u32]) -> DecodeSettings {
    DecodeSettings {
        apple_classes: apple_classes.to_vec(),
        score_threshold: 0.25,
        iou_threshold: 0.45,
        max_detections: 100,
        clip_level: 250,
    }
}

/// A grey 128x64 image whose right half is clipped white.
fn image() -> Vec<u8> {
    let mut data = Vec::new();
    for _ in 0..64 {
        for u in 0..128 {
            data.extend_from_slice(if u < 64 {
                &[120, 40, 30]
            } else {
                &[255, 255, 255]
            });
        }
    }
    data
}

#[test]
fn a_detect_head_gives_nms_filtered_apples_with_ellipse_masks_in_image_pixels() {
    // Image 128x64 on a 64 px input: scale 0.5, 16 px of padding above.
    let letterbox = Letterbox::new(128, 64, 64);
    let layout = YoloLayout {
        head: YoloHead::Detect,
        classes: 2,
        input_size_px: 64,
        predictions_output: 0,
    };
    let data = tensor(&[
        vec![32.0, 32.0, 16.0, 16.0, 0.9, 0.0],
        vec![33.0, 32.0, 16.0, 16.0, 0.8, 0.0], // the same fruit: suppressed
        vec![10.0, 30.0, 8.0, 8.0, 0.1, 0.95],  // a leaf
    ]);
    let pixels = image();
    let rgb = RgbView {
        width_px: 128,
        height_px: 64,
        data: &pixels,
    };
    let mut decoder = YoloDecoder::new(layout, settings(&[0]));
    let mut detections = Vec::new();
    let shape = [1, 6, 3];
    let info = decoder
        .decode(
            OutputTensor {
                shape: &shape,
                data: &data,
            },
            None,
            &letterbox,
            &rgb,
            &mut detections,
        )
        .expect("decode");
    assert_eq!(info.candidate_regions, 2);
    assert_eq!(detections.len(), 1);
    let apple = &detections[0];
    assert_eq!(
        apple.pixel_box,
        PixelBox {
            u_min_px: 48,
            v_min_px: 16,
            u_max_px: 80,
            v_max_px: 48
        }
    );
    assert_eq!(apple.confidence, 0.9);
    assert_eq!(apple.source, DetectionSource::Model);
    assert!(apple.mask.contains_px(64, 32) && !apple.mask.contains_px(49, 17));
    // The ellipse of a 32 px box, half of it over the clipped half of the image.
    let disc_px = std::f64::consts::PI * 16.0 * 16.0;
    assert!((f64::from(apple.visible_px) - disc_px).abs() < 0.05 * disc_px);
    assert!(
        (apple.saturated_fraction - 0.5).abs() < 0.1,
        "{}",
        apple.saturated_fraction
    );

    // A wrong shape at run time is an error naming it, not a panic.
    let wrong = [1, 7, 3];
    let error = decoder
        .decode(
            OutputTensor {
                shape: &wrong,
                data: &data,
            },
            None,
            &letterbox,
            &rgb,
            &mut detections,
        )
        .expect_err("7 channels");
    assert_eq!(
        error.to_string(),
        "predictions output has shape [1, 7, 3], expected [1, 6, N]"
    );
}

#[test]
fn a_segment_head_masks_each_apple_from_its_coefficients() {
    let letterbox = Letterbox::new(128, 64, 64);
    let layout = YoloLayout {
        head: YoloHead::Segment { protos_output: 1 },
        classes: 1,
        input_size_px: 64,
        predictions_output: 0,
    };
    // Prototype 0: apple left of prototype column 8 (input x = 32, image u = 64).
    let (h, w) = (16usize, 16usize);
    let mut protos = vec![0.0f32; 32 * h * w];
    for y in 0..h {
        for x in 0..w {
            protos[y * w + x] = if x < 8 { 10.0 } else { -10.0 };
        }
    }
    let row = |cx: f32, score: f32, coefficient: f32| {
        let mut row = vec![cx, 32.0, 16.0, 16.0, score, coefficient];
        row.extend(std::iter::repeat_n(0.0, 31));
        row
    };
    // Anchor 0 keeps the left of its box, anchor 1 (far right, inverted coefficient) the
    // right of its own.
    let data = tensor(&[row(32.0, 0.9, 1.0), row(52.0, 0.7, -1.0)]);
    let pixels = image();
    let rgb = RgbView {
        width_px: 128,
        height_px: 64,
        data: &pixels,
    };
    let mut decoder = YoloDecoder::new(layout, settings(&[0]));
    let mut detections = Vec::new();
    let (shape, protos_shape) = ([1, 37, 2], [1, 32, 16, 16]);
    decoder
        .decode(
            OutputTensor {
                shape: &shape,
                data: &data,
            },
            Some(OutputTensor {
                shape: &protos_shape,
                data: &protos,
            }),
            &letterbox,
            &rgb,
            &mut detections,
        )
        .expect("decode");
    assert_eq!(detections.len(), 2);
    let left = &detections[0];
    // Cells centred at u = 49..63 (8) by v = 17..47 (16), 4 px each.
    assert_eq!(left.mask.set_cell_count(), 128);
    assert_eq!(left.visible_px, 512);
    assert!(left.mask.contains_px(60, 30) && !left.mask.contains_px(70, 30));
    assert_eq!(left.saturated_fraction, 0.0);
    let right = &detections[1];
    assert_eq!(right.pixel_box.u_min_px, 88);
    assert!(right.mask.contains_px(100, 30));
    assert_eq!(right.saturated_fraction, 1.0);
    // No prototypes for a segment head: refused.
    let error = decoder
        .decode(
            OutputTensor {
                shape: &shape,
                data: &data,
            },
            Some(OutputTensor {
                shape: &[1, 16, 16, 16],
                data: &protos,
            }),
            &letterbox,
            &rgb,
            &mut detections,
        )
        .expect_err("16 prototypes");
    assert!(error.to_string().contains("[1, 16, 16, 16]"), "{error}");
}
