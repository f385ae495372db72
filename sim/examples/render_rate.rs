//! Prints the single-thread render rate of a scenario preset.
//! Usage: `cargo run --release -p harvest-sim --example render_rate -- [preset] [frames]`

#![forbid(unsafe_code)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]

use harvest_sim::render_rate::measure_render_rate;
use harvest_sim::scenario::Scenario;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let preset = args.next().unwrap_or_else(|| "default".to_owned());
    let frames: u32 = args.next().map_or(Ok(60), |f| f.parse())?;
    let scenario = Scenario::preset(&preset)?;
    let rate = measure_render_rate(&scenario, 1, frames)?;
    println!(
        "{preset}, {} frames, one thread (per CPU-second / per wall-second):",
        rate.frames
    );
    for (kind, r) in [
        ("rgb 1920x1080", rate.color),
        ("depth 640x480", rate.depth),
        ("rgb + depth", rate.rgbd),
    ] {
        println!(
            "  {kind:<14} {:7.1} fps cpu  {:7.1} fps wall",
            r.cpu_fps, r.wall_fps
        );
    }
    Ok(())
}
