use super::*;
use crate::scenario::Scenario;

struct Frames {
    rgb: Vec<u8>,
    depth_mm: Vec<u16>,
    labels: Vec<u32>,
}

fn render(world: &World, frame_seq: u64) -> (RgbdRenderer, Frames) {
    let mut renderer = RgbdRenderer::new(&world.scenario().camera).expect("renderer");
    let color = *renderer.color_intrinsics();
    let depth = *renderer.depth_intrinsics();
    let color_px = (color.width_px * color.height_px) as usize;
    let mut frames = Frames {
        rgb: vec![0; 3 * color_px],
        depth_mm: vec![0; (depth.width_px * depth.height_px) as usize],
        labels: vec![0; color_px],
    };
    renderer.render_color(world, &mut frames.rgb).expect("rgb");
    renderer
        .render_depth(world, frame_seq, &mut frames.depth_mm)
        .expect("depth");
    renderer
        .render_labels(world, &mut frames.labels)
        .expect("labels");
    (renderer, frames)
}

fn ideal_world() -> World {
    World::generate(&Scenario::preset("ideal").expect("ideal"), 4).expect("world")
}

fn pixel_index(intrinsics: &CameraIntrinsics, u: f64, v: f64) -> usize {
    v.round() as usize * intrinsics.width_px as usize + u.round() as usize
}

#[test]
fn projected_apple_centres_land_on_their_rendered_pixels() {
    let world = ideal_world();
    let (renderer, frames) = render(&world, 0);
    let color = renderer.color_intrinsics();
    let depth = renderer.depth_intrinsics();
    let color_from_robot = renderer.robot_from_color().inverse();
    let depth_from_robot = renderer.robot_from_depth().inverse();
    for apple in world.apples() {
        let in_color = color_from_robot.apply(apple.center_in_robot_m);
        let (u, v) = color.project(in_color).expect("in front");
        assert!(color.contains(u, v), "apple {:?} off-image", apple.id);
        let pixel = pixel_index(color, u, v);
        assert_eq!(apple_from_label(frames.labels[pixel]), Some(apple.id));
        let [r, g, b] = [0, 1, 2].map(|k| frames.rgb[3 * pixel + k]);
        assert!(
            r > g && r > b,
            "apple {:?} pixel is not red: {r} {g} {b}",
            apple.id
        );
        // Depth at the projected centre is the near surface: z_centre - r (to first order).
        let in_depth = depth_from_robot.apply(apple.center_in_robot_m);
        let (u, v) = depth.project(in_depth).expect("in front");
        let measured_mm = f64::from(frames.depth_mm[pixel_index(depth, u, v)]);
        let surface_mm = 1000.0 * (in_depth[2] - apple.radius_m);
        let sigma_mm = world.scenario().camera.depth_sigma_mm(surface_mm);
        assert!(
            (measured_mm - surface_mm).abs() < 5.0 * sigma_mm + 3.0,
            "apple {:?}: depth {measured_mm} mm, expected {surface_mm:.1} mm",
            apple.id
        );
    }
}

#[test]
fn depth_noise_matches_the_spec_on_a_flat_patch() {
    // The next tree row is a plane of constant robot x; with a camera looking straight along
    // robot x it is a plane of constant depth.
    let mut scenario = Scenario::preset("ideal").expect("ideal");
    scenario.apples.count = 0;
    scenario.camera.position_in_robot_m = [0.0, 0.0, 0.5];
    scenario.camera.look_at_in_robot_m = [3.0, 0.0, 0.5];
    let world = World::generate(&scenario, 9).expect("world");
    let mut renderer = RgbdRenderer::new(&scenario.camera).expect("renderer");
    let depth = *renderer.depth_intrinsics();
    let mut frame = vec![0u16; (depth.width_px * depth.height_px) as usize];
    let truth_mm = 1000.0 * scenario.background.next_row_x_m;
    let expected_sigma_mm = scenario.camera.depth_sigma_mm(truth_mm);
    let (mut sum, mut sum_sq, mut count) = (0.0f64, 0.0f64, 0usize);
    for frame_seq in 0..4 {
        renderer
            .render_depth(&world, frame_seq, &mut frame)
            .expect("depth");
        // A 200x100 patch around the centre, all on the next row.
        for v in 190..290 {
            for u in 220..420 {
                let error = f64::from(frame[v * depth.width_px as usize + u]) - truth_mm;
                sum += error;
                sum_sq += error * error;
                count += 1;
            }
        }
    }
    let mean = sum / count as f64;
    let std = (sum_sq / count as f64 - mean * mean).sqrt();
    // Standard error of the mean is sigma / sqrt(80000), about 0.04 mm.
    assert!(mean.abs() < 0.3, "mean error {mean} mm");
    // Rounding to whole millimetres adds 1/12 mm^2 of variance.
    let expected_std = (expected_sigma_mm.powi(2) + 1.0 / 12.0).sqrt();
    assert!(
        (std / expected_std - 1.0).abs() < 0.02,
        "std {std} mm, expected {expected_std} mm"
    );
}

#[test]
fn out_of_range_reads_zero_and_sky_has_no_return() {
    let mut scenario = Scenario::preset("ideal").expect("ideal");
    scenario.camera.look_at_in_robot_m = [2.0, 0.0, 2.5];
    let world = World::generate(&scenario, 1).expect("world");
    let (renderer, frames) = render(&world, 0);
    // Looking up: the top rows see sky.
    let width = renderer.depth_intrinsics().width_px as usize;
    assert!(frames.depth_mm[..width].iter().all(|&d| d == 0));
    assert!(frames.labels[..100].iter().all(|&l| l == label::SKY));
    let sky = scenario.background.sky_rgb;
    assert_eq!(&frames.rgb[..3], &sky);
}

#[test]
fn occluding_leaves_hide_apple_pixels() {
    let mut scenario = Scenario::preset("ideal").expect("ideal");
    scenario.failures.heavy_occlusion = 1.0;
    let world = World::generate(&scenario, 2).expect("world");
    let (_, occluded) = render(&world, 0);
    let (_, clear) = render(&ideal_world(), 0);
    let apple_pixels = |labels: &[u32]| labels.iter().filter(|&&l| l >= label::APPLE_BASE).count();
    let (hidden, visible) = (apple_pixels(&occluded.labels), apple_pixels(&clear.labels));
    assert!(
        hidden * 2 < visible,
        "occluded {hidden} vs clear {visible} apple pixels"
    );
}

#[test]
fn overexposure_saturates_the_apple_and_corrupts_its_depth() {
    let mut scenario = Scenario::preset("ideal").expect("ideal");
    scenario.failures.camera_overexposure = 1.0;
    let world = World::generate(&scenario, 4).expect("world");
    let (renderer, frames) = render(&world, 0);
    let (_, clean) = render(&ideal_world(), 0);
    let color = renderer.color_intrinsics();
    let color_from_robot = renderer.robot_from_color().inverse();
    for apple in world.apples() {
        let (u, v) = color
            .project(color_from_robot.apply(apple.center_in_robot_m))
            .expect("front");
        let pixel = pixel_index(color, u, v);
        assert!(
            frames.rgb[3 * pixel..3 * pixel + 3]
                .iter()
                .all(|&c| c == 255)
        );
    }
    let dropouts = |d: &[u16]| d.iter().filter(|&&z| z == 0).count();
    assert!(dropouts(&frames.depth_mm) > dropouts(&clean.depth_mm) + 100);
}

#[test]
fn overexposure_leaves_occluders_in_their_own_colour() {
    // Every apple over-exposed and most of them behind extra leaves.
    let mut scenario = Scenario::preset("default").expect("default");
    scenario.failures.camera_overexposure = 1.0;
    scenario.failures.heavy_occlusion = 1.0;
    let world = World::generate(&scenario, 7).expect("world");
    let (_, glaring) = render(&world, 0);
    // The same world rendered without any highlight.
    let mut camera = scenario.camera.clone();
    camera.overexposed_patch_scale = 0.0;
    let mut renderer = RgbdRenderer::new(&camera).expect("renderer");
    let mut plain = vec![0u8; glaring.rgb.len()];
    renderer.render_color(&world, &mut plain).expect("rgb");
    let (mut occluder_pixels, mut saturated_apple_pixels) = (0usize, 0usize);
    for (pixel, &label) in glaring.labels.iter().enumerate() {
        let rgb = 3 * pixel..3 * pixel + 3;
        if apple_from_label(label).is_some() {
            if glaring.rgb[rgb.clone()] != plain[rgb.clone()]
                && glaring.rgb[rgb].iter().all(|&c| c >= 250)
            {
                saturated_apple_pixels += 1;
            }
        } else {
            assert_eq!(
                glaring.rgb[rgb.clone()],
                plain[rgb],
                "pixel {pixel} (label {label}) changed by an apple's highlight"
            );
            if label == label::LEAF || label == label::WOOD {
                occluder_pixels += 1;
            }
        }
    }
    assert!(
        occluder_pixels > 100_000,
        "{occluder_pixels} occluder pixels"
    );
    assert!(
        saturated_apple_pixels > 10_000,
        "{saturated_apple_pixels} saturated apple pixels"
    );
}

#[test]
fn same_seed_and_frame_give_identical_frames() {
    let world = World::generate(&Scenario::preset("default").expect("default"), 21).expect("world");
    let (_, a) = render(&world, 5);
    let (_, b) = render(&world, 5);
    let (_, c) = render(&world, 6);
    assert!(a.rgb == b.rgb && a.depth_mm == b.depth_mm && a.labels == b.labels);
    assert!(a.depth_mm != c.depth_mm, "noise differs between frames");
    assert!(a.rgb == c.rgb);
}

#[test]
fn wrong_buffer_sizes_are_refused() {
    let world = ideal_world();
    let mut renderer = RgbdRenderer::new(&world.scenario().camera).expect("renderer");
    let error = renderer
        .render_color(&world, &mut [0u8; 10])
        .expect_err("size");
    assert!(matches!(
        error,
        RenderError::BufferSize {
            buffer: "rgb",
            actual: 10,
            ..
        }
    ));
    assert!(renderer.render_depth(&world, 0, &mut [0u16; 10]).is_err());
}
