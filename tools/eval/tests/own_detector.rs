//! harvest's own ONNX model (`models/apple_net_640.onnx`, trained by tools/detector_training/ on
//! the simulator's renders) in the perception evaluation, through the real ONNX Runtime (PyPI's
//! `onnxruntime` wheel, found as in production): on worlds it was not trained on (evaluation
//! seeds; training used seeds from 100000), it finds most apples that are at least half
//! visible, reports (almost) nothing on frames without apples, and its masks (the segment head's)
//! localize the apples within the 3D error target.
//! The full figures are `harvest eval perception --detector onnx --model ...`
//! (docs/evaluation.md); this test checks a small run with margins below them.

use harvest_test_support::python::ensure_python;
use std::path::Path;

use harvest_eval::{EvalPerceptionArgs, run_eval_perception};
use harvest_perception::depth_source::DepthSource;
use harvest_perception::detector::DetectorKind;
use harvest_perception::estimator::EstimatorKind;

#[test]
fn the_committed_model_finds_apples_on_unseen_worlds() {
    ensure_python("onnxruntime", &["onnxruntime"]);
    let model = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models/apple_net_640.onnx");
    assert!(model.is_file(), "{} is missing", model.display());
    let args = EvalPerceptionArgs {
        scenario: vec!["default".to_owned()],
        frames: 4,
        empty_frames: Some(2),
        seed: 1,
        json: None,
        estimators: vec![EstimatorKind::SphereFit],
        depth_sources: vec![DepthSource::Tof],
        lidar_integration_s: 1.0,
        table_iii_trials: 0,
        detector: Some(DetectorKind::Onnx),
        model: Some(model),
    };
    let report = run_eval_perception(&args).expect("evaluation runs");
    assert_eq!(report.detector, "onnx");
    let detection = &report.scenarios[0].estimators[0].detection;
    let recall = detection.recall_half_visible.expect("apples half visible");
    let precision = detection.precision.expect("detections");
    assert!(recall >= MIN_RECALL, "recall (>= 50 % visible) {recall:.3}");
    assert!(precision >= MIN_PRECISION, "precision {precision:.3}");
    // The full evaluation reports one box on 1 of its 60 empty frames; this check tolerates one
    // and no more.
    assert!(
        detection.empty_frame_detections <= MAX_EMPTY_FRAME_DETECTIONS,
        "{} apples reported on frames without apples",
        detection.empty_frame_detections
    );
    // The segment head's masks keep the leaves and neighbours in front of an apple out of its
    // sphere fit: the earlier detect-only model, which fitted the ellipse inscribed in each box,
    // had 28 mm here.
    let p95_mm = report.scenarios[0].estimators[0]
        .error_mm
        .p95
        .expect("matched apples");
    assert!(p95_mm <= MAX_P95_ERROR_MM, "p95 3D error {p95_mm:.1} mm");
}

/// Margins below the model's figures over 30 worlds (docs/evaluation.md).
const MIN_RECALL: f64 = 0.8;
const MIN_PRECISION: f64 = 0.85;
const MAX_EMPTY_FRAME_DETECTIONS: usize = 1;
/// The target (the run gives 9.0 mm, the full evaluation 8.9).
const MAX_P95_ERROR_MM: f64 = 15.0;
