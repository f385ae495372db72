//! The ONNX detector end to end through the real ONNX Runtime (PyPI's `onnxruntime` wheel, found
//! as in production): tiny YOLO-layout models written by `yolo_models.py` with the Python `onnx`
//! package, whose outputs ONNX Runtime computes from the letterboxed frame.
//!
//! Checks: a detect model's apple comes back at the image box of the red block the model saw; a
//! segment model's mask is the red block inside a larger box; a model of another layout, a fixed
//! input size other than the configured one, and a class the model lacks are refused at start
//! with the shapes named; a missing GPU provider falls back to the CPU, or with `require_gpu`
//! refuses to start.

use harvest_test_support::python::ensure_python;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

use harvest_perception::RgbView;
use harvest_perception::detector::onnx::{ExecutionProvider, OnnxDetector, OnnxDetectorConfig};
use harvest_perception::detector::yolo::layout::YoloHead;
use harvest_perception::detector::{Detection, DetectionSource, Detector, PixelBox};

/// The directory holding detect.onnx, segment.onnx and end2end.onnx (written once per run).
fn models() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        ensure_python("onnx, onnxruntime", &["onnx", "onnxruntime"]);
        let dir = std::env::temp_dir().join(format!("harvest-yolo-models-{}", std::process::id()));
        let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/yolo_models.py");
        let status = Command::new("python3")
            .arg(&script)
            .arg(&dir)
            .status()
            .expect("run yolo_models.py");
        assert!(status.success(), "yolo_models.py failed");
        dir
    })
}

fn config(model: &str) -> OnnxDetectorConfig {
    OnnxDetectorConfig {
        input_size: 64,
        ..OnnxDetectorConfig::with_model(models().join(model))
    }
}

/// A 128x64 dark grey frame with a red 16x16 block at u 32..48, v 16..32. Letterboxed onto 64 px
/// (scale 0.5, 16 px of padding above) the block is exactly the model's stride-8 cell (2, 3).
fn frame() -> Vec<u8> {
    let mut data = Vec::with_capacity(128 * 64 * 3);
    for v in 0..64 {
        for u in 0..128 {
            let red = (32..48).contains(&u) && (16..32).contains(&v);
            data.extend_from_slice(if red { &[255, 0, 0] } else { &[0, 60, 40] });
        }
    }
    data
}

fn detect(detector: &mut OnnxDetector) -> Vec<Detection> {
    let data = frame();
    let rgb = RgbView {
        width_px: 128,
        height_px: 64,
        data: &data,
    };
    let mut detections = Vec::new();
    detector.detect(&rgb, &mut detections).expect("detect");
    detections
}

#[test]
fn a_detect_model_finds_the_block_it_saw_at_its_image_box() {
    let mut detector = OnnxDetector::new(&config("detect.onnx")).expect("detector");
    assert_eq!(detector.layout().head, YoloHead::Detect);
    assert_eq!(detector.layout().classes, 2);
    assert_eq!(detector.provider(), ExecutionProvider::Cpu);
    let detections = detect(&mut detector);
    assert_eq!(detections.len(), 1, "{detections:?}");
    let apple = &detections[0];
    assert_eq!(
        apple.pixel_box,
        PixelBox {
            u_min_px: 32,
            v_min_px: 16,
            u_max_px: 48,
            v_max_px: 32
        }
    );
    assert!(
        (apple.confidence - 1.0).abs() < 1e-5,
        "{}",
        apple.confidence
    );
    assert_eq!(apple.source, DetectionSource::Model);
    // A detect head's mask is the box's inscribed ellipse.
    assert!(apple.mask.contains_px(40, 24) && !apple.mask.contains_px(32, 16));
    // The same frame again: the same answer (the model is deterministic, the buffers reused).
    assert_eq!(detect(&mut detector), detections);
}

#[test]
fn a_segment_model_masks_the_red_block_inside_its_larger_box() {
    let mut detector = OnnxDetector::new(&config("segment.onnx")).expect("detector");
    assert!(matches!(detector.layout().head, YoloHead::Segment { .. }));
    let detections = detect(&mut detector);
    assert_eq!(detections.len(), 1, "{detections:?}");
    let apple = &detections[0];
    // 24 input px around cell (2, 3): input x 8..32, y 16..40 -> image u 16..64, v 0..48.
    assert_eq!(
        apple.pixel_box,
        PixelBox {
            u_min_px: 16,
            v_min_px: 0,
            u_max_px: 64,
            v_max_px: 48
        }
    );
    // The mask is the 16x16 block (64 cells of 2x2 px) with its corners rounded by the bilinear
    // upsampling of the 4 px prototype grid, and nothing outside the block.
    let cells = apple.mask.set_cell_count();
    assert!((56..=64).contains(&cells), "{cells} cells");
    assert_eq!(apple.visible_px as usize, 4 * cells);
    for v in 0..64 {
        for u in 0..128 {
            let in_block = (32..48).contains(&u) && (16..32).contains(&v);
            assert!(
                in_block || !apple.mask.contains_px(u, v),
                "({u}, {v}) outside the block"
            );
        }
    }
    for (u, v) in [(33, 24), (47, 24), (40, 17), (40, 31), (40, 24)] {
        assert!(apple.mask.contains_px(u, v), "({u}, {v})");
    }
}

#[test]
fn models_of_other_layouts_sizes_or_classes_are_refused_at_start() {
    let message = OnnxDetector::new(&config("end2end.onnx"))
        .expect_err("end-to-end head")
        .to_string();
    assert!(
        message.contains("end2end.onnx")
            && message.contains("images [1, 3, 64, 64] f32")
            && message.contains("output0 [1, 300, 6] f32")
            && message.contains("[1, 4+nc, N]")
            && message.contains("[1, 4+nc+32, N] and [1, 32, H/4, W/4]"),
        "{message}"
    );
    let size = OnnxDetector::new(&OnnxDetectorConfig {
        input_size: 640,
        ..config("detect.onnx")
    })
    .expect_err("fixed at 64")
    .to_string();
    assert!(
        size.contains("fixed at 64 px") && size.contains("input_size = 640"),
        "{size}"
    );
    let class = OnnxDetector::new(&OnnxDetectorConfig {
        classes: vec![0, 5],
        ..config("detect.onnx")
    })
    .expect_err("class 5")
    .to_string();
    assert!(class.contains("classes = 5"), "{class}");
    let missing = OnnxDetector::new(&config("missing.onnx"))
        .expect_err("no file")
        .to_string();
    assert!(missing.contains("missing.onnx"), "{missing}");
}

#[test]
fn a_missing_gpu_provider_falls_back_or_with_require_gpu_refuses_to_start() {
    // The CPU wheel has neither CUDA nor TensorRT.
    let mut detector = OnnxDetector::new(&OnnxDetectorConfig {
        providers: vec![
            ExecutionProvider::Tensorrt,
            ExecutionProvider::Cuda,
            ExecutionProvider::Cpu,
        ],
        ..config("detect.onnx")
    })
    .expect("falls back to the CPU");
    assert_eq!(detector.provider(), ExecutionProvider::Cpu);
    assert_eq!(detect(&mut detector).len(), 1);
    let message = OnnxDetector::new(&OnnxDetectorConfig {
        providers: vec![ExecutionProvider::Cuda, ExecutionProvider::Cpu],
        require_gpu: true,
        ..config("detect.onnx")
    })
    .expect_err("require_gpu")
    .to_string();
    assert!(
        message.contains("require_gpu")
            && message.contains("cuda")
            && message.contains("onnxruntime-gpu"),
        "{message}"
    );
}
