//! Writes one RGB frame, one depth frame (scaled to 8 bits) and one label frame of a preset as
//! PNGs, for looking at the simulated camera.
//! Usage: `cargo run -p harvest-sim --example render_png -- [preset] [seed] [out_dir]`

#![forbid(unsafe_code)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]

use harvest_sim::World;
use harvest_sim::render_rgbd::{RgbdRenderer, apple_from_label, label};
use harvest_sim::scenario::Scenario;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let preset = args.next().unwrap_or_else(|| "default".to_owned());
    let seed: u64 = args.next().map_or(Ok(1), |s| s.parse())?;
    let out_dir = std::path::PathBuf::from(args.next().unwrap_or_else(|| ".".to_owned()));
    let scenario = Scenario::preset(&preset)?;
    let world = World::generate(&scenario, seed)?;
    let mut renderer = RgbdRenderer::new(&scenario.camera)?;
    let color = *renderer.color_intrinsics();
    let depth = *renderer.depth_intrinsics();
    let mut rgb = vec![0u8; 3 * (color.width_px * color.height_px) as usize];
    let mut depth_mm = vec![0u16; (depth.width_px * depth.height_px) as usize];
    let mut labels = vec![0u32; (color.width_px * color.height_px) as usize];
    renderer.render_color(&world, &mut rgb)?;
    renderer.render_depth(&world, 0, &mut depth_mm)?;
    renderer.render_labels(&world, &mut labels)?;
    image::save_buffer(
        out_dir.join(format!("{preset}_rgb.png")),
        &rgb,
        color.width_px,
        color.height_px,
        image::ColorType::Rgb8,
    )?;
    // 0.5-4 m mapped to 255-0; no return black.
    let depth8: Vec<u8> = depth_mm
        .iter()
        .map(|&d| {
            if d == 0 {
                0
            } else {
                (255.0 * (1.0 - (f64::from(d) - 500.0) / 3500.0)).clamp(1.0, 255.0) as u8
            }
        })
        .collect();
    image::save_buffer(
        out_dir.join(format!("{preset}_depth.png")),
        &depth8,
        depth.width_px,
        depth.height_px,
        image::ColorType::L8,
    )?;
    let label8: Vec<u8> = labels
        .iter()
        .map(|&l| match l {
            label::LEAF => 90,
            label::WOOD => 50,
            _ if apple_from_label(l).is_some() => 255,
            _ => 0,
        })
        .collect();
    image::save_buffer(
        out_dir.join(format!("{preset}_labels.png")),
        &label8,
        color.width_px,
        color.height_px,
        image::ColorType::L8,
    )?;
    println!(
        "wrote {preset}_{{rgb,depth,labels}}.png to {}",
        out_dir.display()
    );
    Ok(())
}
