//! End-to-end interval scan on the in-process rendered ALACS: plan, move, capture, extract,
//! triangulate, fit candidates, select; with and without a leaf hiding part of the apple.

use harvest_hw::alacs::{AlacsExtrinsics, AlacsUnit, alacs_camera_intrinsics};
use harvest_ipc::camera_model::CameraIntrinsics;
use harvest_laser::{
    PixelRoi, ProcessorConfig, ScanConfig, ScanPlanner, ScanProcessor, TargetHint, run_scan,
};
use harvest_sim::alacs::{AlacsScene, AppleSphere, LeafDisc, RenderedAlacs, RenderedAlacsConfig};

fn camera() -> CameraIntrinsics {
    // Half the ALACS camera's resolution, same field of view, to keep the test quick.
    let mut intrinsics = alacs_camera_intrinsics();
    intrinsics.width_px = 720;
    intrinsics.height_px = 540;
    intrinsics.fx_px *= 0.5;
    intrinsics.fy_px *= 0.5;
    intrinsics.cx_px = 359.5;
    intrinsics.cy_px = 269.5;
    intrinsics
}

fn hint_for(intrinsics: &CameraIntrinsics, apple: &AppleSphere) -> TargetHint {
    let centre = apple.centre_in_camera_m;
    let distance = centre.iter().map(|c| c * c).sum::<f64>().sqrt();
    let (u, v) = intrinsics.project(centre).expect("visible");
    let radius_px = intrinsics.fx_px * (apple.radius_m / distance).asin().tan();
    TargetHint {
        bbox_px: PixelRoi {
            u_min_px: (u - radius_px).round() as usize,
            v_min_px: (v - radius_px).round() as usize,
            u_max_px: (u + radius_px).round() as usize,
            v_max_px: (v + radius_px).round() as usize,
        },
        // The RGB-D estimate: 1.5 cm off in depth, a few mm sideways.
        rough_centre_in_camera_m: [centre[0] + 0.004, centre[1] - 0.003, centre[2] + 0.015],
    }
}

fn scan(scene: AlacsScene) -> (harvest_laser::ScanResult, [f64; 3]) {
    let intrinsics = camera();
    let apple = scene.apples[0];
    let config = RenderedAlacsConfig::default();
    let extrinsics = config.extrinsics;
    let mut unit = RenderedAlacs::new(intrinsics, config, scene).expect("unit");
    let planner = ScanPlanner {
        extrinsics,
        config: ScanConfig::default(),
    };
    let mut processor =
        ScanProcessor::new(unit.intrinsics(), extrinsics, ProcessorConfig::default())
            .expect("processor");
    let mut rgb = Vec::new();
    let result = run_scan(
        &mut unit,
        &planner,
        &mut processor,
        &hint_for(&intrinsics, &apple),
        &mut rgb,
    )
    .expect("scan");
    (result, apple.centre_in_camera_m)
}

fn apple_at(depth_m: f64) -> AppleSphere {
    AppleSphere {
        centre_in_camera_m: [-0.03, 0.04, depth_m],
        radius_m: 0.04,
        rgb: [150, 30, 25],
    }
}

fn error_m(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>().sqrt()
}

#[test]
fn scan_of_a_clear_apple_finds_its_centre() {
    for depth_m in [0.7, 1.1] {
        let scene = AlacsScene {
            apples: vec![apple_at(depth_m)],
            background_depth_m: Some(depth_m + 0.4),
            ..AlacsScene::default()
        };
        let (result, truth) = scan(scene);
        assert_eq!(result.candidates.len(), 5);
        let valid = result.candidates.iter().filter(|c| c.is_ok()).count();
        assert!(valid >= 4, "{:?}", result.candidates);
        let error = error_m(result.centre_in_camera_m, truth);
        assert!(error < 5e-3, "depth {depth_m}: {error} m, {result:?}");
    }
}

#[test]
fn scan_behind_a_leaf_still_finds_the_centre() {
    let apple = apple_at(0.9);
    let centre = apple.centre_in_camera_m;
    let scene = AlacsScene {
        apples: vec![apple],
        // A leaf 3 cm in front hiding the apple's lower left quarter.
        leaves: vec![LeafDisc {
            centre_in_camera_m: [centre[0] - 0.03, centre[1] + 0.03, centre[2] - 0.07],
            normal: [0.1, -0.1, -1.0],
            radius_m: 0.035,
            rgb: [50, 110, 40],
        }],
        background_depth_m: Some(1.3),
        ..AlacsScene::default()
    };
    let (result, truth) = scan(scene);
    let error = error_m(result.centre_in_camera_m, truth);
    assert!(error < 6e-3, "{error} m, {result:?}");
}

#[test]
fn scan_without_an_apple_reports_every_image() {
    let intrinsics = camera();
    let scene = AlacsScene {
        background_depth_m: Some(1.0),
        ..AlacsScene::default()
    };
    let extrinsics = AlacsExtrinsics::paper_table1();
    let mut unit =
        RenderedAlacs::new(intrinsics, RenderedAlacsConfig::default(), scene).expect("unit");
    let planner = ScanPlanner {
        extrinsics,
        config: ScanConfig::default(),
    };
    let mut processor =
        ScanProcessor::new(intrinsics, extrinsics, ProcessorConfig::default()).expect("processor");
    let hint = hint_for(&intrinsics, &apple_at(0.9));
    let error = run_scan(&mut unit, &planner, &mut processor, &hint, &mut Vec::new())
        .expect_err("nothing to find");
    match error {
        harvest_laser::ScanError::NoCandidate(failure) => {
            assert_eq!(failure.candidates.len(), 5);
        }
        other => panic!("unexpected {other}"),
    }
}
