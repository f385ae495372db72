//! Domain randomisation of a scenario for the detector's training data: what the renderer lets
//! vary (sun direction from front-lit to backlit, sun, ambient and specular strength, how many
//! apples glare and how far the glare spreads, the colours of apple varieties, leaves, wood and
//! background, occlusion and clustering, the canopy's distance), drawn from a seeded generator so
//! a data set is reproduced by its seed.

use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use serde::Serialize;

use harvest_sim::Scenario;

/// A variety: name, blush colour, ground colour (RGB) and the blush fraction range.
type Variety = (&'static str, [u8; 3], [u8; 3], [f64; 2]);

/// Apple varieties' skin colours: blush and ground colour (RGB) and the blush fraction range.
/// Red, striped, yellow and green cultivars, so the model learns shape and shading, not one hue.
const VARIETIES: [Variety; 7] = [
    ("gala", [186, 46, 34], [216, 190, 80], [0.5, 0.85]),
    ("fuji", [168, 42, 56], [204, 196, 104], [0.6, 0.95]),
    ("red_delicious", [120, 18, 30], [150, 60, 40], [0.8, 1.0]),
    ("honeycrisp", [196, 60, 40], [220, 200, 110], [0.3, 0.7]),
    (
        "golden_delicious",
        [226, 190, 70],
        [214, 200, 96],
        [0.1, 0.4],
    ),
    ("granny_smith", [150, 190, 70], [120, 176, 64], [0.0, 0.2]),
    ("pink_lady", [214, 84, 96], [200, 200, 110], [0.3, 0.6]),
];

/// What was drawn for one world (written beside its image).
#[derive(Debug, Clone, Serialize)]
pub struct Draw {
    pub variety: &'static str,
    pub sun_direction_in_robot: [f64; 3],
    /// True when the sun is behind the canopy (seen from the camera).
    pub backlit: bool,
    pub sun_intensity: f64,
    pub ambient: f64,
    pub specular: f64,
    pub camera_overexposure: f64,
}

fn jitter(rng: &mut SmallRng, rgb: [u8; 3], fraction: f64) -> [u8; 3] {
    rgb.map(|c| {
        let factor = 1.0 + rng.random_range(-fraction..=fraction);
        (f64::from(c) * factor).round().clamp(0.0, 255.0) as u8
    })
}

/// A randomised copy of `base` for world `seed` (the same seed draws the same scenario).
pub fn randomize(base: &Scenario, seed: u64) -> (Scenario, Draw) {
    // A stream of its own, apart from the world generator's (which takes the same seed).
    let mut rng = SmallRng::seed_from_u64(seed ^ 0x5eed_da7a_5e7d_0001);
    let mut s = base.clone();
    let (variety, blush, ground, fraction) = VARIETIES[rng.random_range(0..VARIETIES.len())];
    s.apples.blush_rgb = jitter(&mut rng, blush, 0.12);
    s.apples.ground_rgb = jitter(&mut rng, ground, 0.12);
    s.apples.blush_fraction = fraction;
    s.apples.colour_jitter = rng.random_range(0.03..0.15);
    s.apples.count = rng.random_range(18..=40);
    s.apples.cluster_probability = rng.random_range(0.1..0.5);
    s.foliage.leaf_rgb = jitter(&mut rng, base.foliage.leaf_rgb, 0.25);
    s.foliage.colour_jitter = rng.random_range(0.08..0.25);
    s.foliage.occlusion_fraction = rng.random_range(0.15..0.45);
    s.foliage.branch_count = rng.random_range(4..=14);
    s.foliage.wood_rgb = jitter(&mut rng, base.foliage.wood_rgb, 0.2);
    s.background.next_row_rgb = jitter(&mut rng, base.background.next_row_rgb, 0.3);
    s.background.ground_rgb = jitter(&mut rng, base.background.ground_rgb, 0.25);
    s.background.sky_rgb = jitter(&mut rng, base.background.sky_rgb, 0.15);
    s.canopy.front_x_m = base.canopy.front_x_m + rng.random_range(-0.15..0.2);
    // Sun anywhere above the horizon; x > 0 puts it behind the canopy (backlit fruit).
    let backlit = rng.random_bool(0.35);
    let x = if backlit {
        rng.random_range(0.2..0.95)
    } else {
        rng.random_range(-0.95..0.2)
    };
    let sun = [x, rng.random_range(-0.7..0.7), rng.random_range(0.15..1.0)];
    s.lighting.sun_direction_in_robot = sun;
    s.lighting.sun_intensity = rng.random_range(0.35..1.2);
    s.lighting.ambient = rng.random_range(0.15..0.6);
    s.lighting.specular = rng.random_range(0.0..0.6);
    s.failures.camera_overexposure = rng.random_range(0.0..0.5);
    s.failures.heavy_occlusion = rng.random_range(0.1..0.5);
    s.camera.overexposed_patch_scale = rng.random_range(1.0..2.2);
    let draw = Draw {
        variety,
        sun_direction_in_robot: sun,
        backlit: sun[0] > 0.0,
        sun_intensity: s.lighting.sun_intensity,
        ambient: s.lighting.ambient,
        specular: s.lighting.specular,
        camera_overexposure: s.failures.camera_overexposure,
    };
    (s, draw)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_same_seed_draws_the_same_scenario_and_seeds_differ() {
        let base = Scenario::preset("default").expect("preset");
        let (a, _) = randomize(&base, 7);
        let (b, _) = randomize(&base, 7);
        let (c, _) = randomize(&base, 8);
        assert_eq!(a, b);
        assert_ne!(a, c);
        // Every draw stays a valid world.
        for seed in 0..20 {
            let (scenario, _) = randomize(&base, seed);
            harvest_sim::World::generate(&scenario, seed).expect("world");
        }
    }
}
