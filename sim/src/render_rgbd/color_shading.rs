//! RGB shading: Lambert diffuse plus a Blinn-Phong highlight on apples under the scenario's sun,
//! an ambient sky term, two-sided translucent leaves, procedural bark and backdrop texture, and
//! the over-exposed apples' saturation.

use harvest_ipc::camera_model::RigidTransform;

use super::backdrop::BackdropHit;
use super::scene::{CylinderPrim, DiscPrim, SpherePrim, glare_weight};
use super::shader::Shader;
use super::{V3, dot, to_f32};
use crate::orchard::World;

/// Integer hash of the unit cell containing `(a, b)` to `[0, 1)`, for cheap procedural texture.
/// The offset keeps the truncating cast equal to `floor` for coordinates above -4096 cells.
#[inline(always)]
pub(super) fn hash01(a: f32, b: f32) -> f32 {
    const OFFSET: f32 = 4096.0;
    let h = (((a + OFFSET) as u32).wrapping_mul(0x8da6_b343))
        ^ (((b + OFFSET) as u32).wrapping_mul(0xd816_3841));
    let h = (h ^ (h >> 13)).wrapping_mul(0x9e37_79b1);
    (h >> 8) as f32 / (1u32 << 24) as f32
}

/// Lit RGB8.
pub(super) struct Colors<'a> {
    pub(super) out: &'a mut [u8],
    /// Unit vector towards the sun, camera frame.
    pub(super) sun: V3,
    /// Blinn half vector between the sun and the viewing direction (-z).
    pub(super) half: V3,
    pub(super) sun_intensity: f32,
    pub(super) ambient: f32,
    pub(super) specular: f32,
    pub(super) next_row: V3,
    pub(super) ground: V3,
    pub(super) sky: V3,
}

impl<'a> Colors<'a> {
    /// Lighting of `world` seen from a camera at `camera_from_robot`, writing into `out`.
    pub(super) fn new(
        world: &World,
        camera_from_robot: &RigidTransform,
        out: &'a mut [u8],
    ) -> Self {
        let scenario = world.scenario();
        let lighting = &scenario.lighting;
        let background = &scenario.background;
        let sun_in_camera = camera_from_robot.rotate(lighting.sun_direction_in_robot);
        let view = [0.0, 0.0, -1.0];
        let half = crate::scenario::normalized(std::array::from_fn(|k| sun_in_camera[k] + view[k]))
            .map_or(to_f32(view), to_f32);
        let linear = |rgb: [u8; 3]| rgb.map(|c| f32::from(c) / 255.0);
        Self {
            out,
            sun: to_f32(sun_in_camera),
            half,
            sun_intensity: lighting.sun_intensity as f32,
            ambient: lighting.ambient as f32,
            specular: lighting.specular as f32,
            next_row: linear(background.next_row_rgb),
            ground: linear(background.ground_rgb),
            sky: linear(background.sky_rgb),
        }
    }

    #[inline(always)]
    fn put(&mut self, pixel: usize, rgb: V3) {
        // Rounded; float-to-int `as` saturates, so values above 255 clip (over-exposure).
        if let Some(out) = self.out.get_mut(3 * pixel..3 * pixel + 3) {
            out[0] = (rgb[0] + 0.5) as u8;
            out[1] = (rgb[1] + 0.5) as u8;
            out[2] = (rgb[2] + 0.5) as u8;
        }
    }
}

impl Shader for Colors<'_> {
    #[inline(always)]
    fn sphere(&mut self, pixel: usize, prim: &SpherePrim, hit: V3) {
        let n = [
            (hit[0] - prim.center[0]) * prim.inv_radius,
            (hit[1] - prim.center[1]) * prim.inv_radius,
            (hit[2] - prim.center[2]) * prim.inv_radius,
        ];
        let diffuse = dot(n, self.sun).max(0.0);
        let mut highlight = dot(n, self.half).max(0.0);
        for _ in 0..4 {
            highlight *= highlight;
        }
        let blush = ((dot(n, prim.blush_axis) - prim.blush_cos) * 2.5 + 0.5).clamp(0.0, 1.0);
        let light = self.ambient + self.sun_intensity * diffuse;
        let shine = self.specular * self.sun_intensity * highlight * 255.0;
        let mut rgb: V3 = std::array::from_fn(|k| {
            let albedo = prim.ground[k] + (prim.blush[k] - prim.ground[k]) * blush;
            albedo * light * 255.0 + shine
        });
        if let Some(glare) = &prim.glare {
            // Sunlight reflected by the apple's own skin saturates it towards white. A later,
            // nearer leaf or branch overwrites this pixel with its own colour.
            let weight = glare_weight(glare, [hit[0] / hit[2], hit[1] / hit[2]]);
            if weight > 0.0 {
                let saturation = (1.6 * weight).min(1.0);
                for c in &mut rgb {
                    let clipped = c.clamp(0.0, 255.0);
                    *c = clipped + (255.0 - clipped) * saturation;
                }
            }
        }
        self.put(pixel, rgb);
    }

    #[inline(always)]
    fn disc(&mut self, pixel: usize, prim: &DiscPrim, across: f32) {
        // The side facing the camera has normal -n.
        let lit = -dot(prim.normal, self.sun);
        // Front-lit blades reflect; back-lit ones glow through (translucency).
        let diffuse = if lit > 0.0 { lit } else { -0.35 * lit };
        let vein = 0.8 + 0.2 * across.abs().min(1.0);
        let light = (self.ambient + self.sun_intensity * diffuse) * vein * 255.0;
        self.put(pixel, prim.rgb.map(|c| c * light));
    }

    #[inline(always)]
    fn cylinder(&mut self, pixel: usize, prim: &CylinderPrim, hit: V3, along: f32) {
        let n = std::array::from_fn(|k| {
            (hit[k] - prim.start[k] - along * prim.axis[k]) * prim.inv_radius
        });
        let diffuse = dot(n, self.sun).max(0.0);
        let bark = 0.85 + 0.3 * hash01(along * 60.0, 0.0);
        let light = (self.ambient + self.sun_intensity * diffuse) * bark * 255.0;
        self.put(pixel, prim.rgb.map(|c| c * light));
    }

    #[inline(always)]
    fn backdrop(&mut self, pixel: usize, hit: BackdropHit) {
        let rgb = match hit {
            BackdropHit::Sky => self.sky.map(|c| c * 255.0),
            BackdropHit::NextRow { y, height, .. } => {
                let texture = 0.55 + 0.6 * hash01(y * 22.0, height * 22.0);
                let light = (self.ambient + 0.5 * self.sun_intensity) * texture * 255.0;
                self.next_row.map(|c| c * light)
            }
            BackdropHit::Ground { x, y, .. } => {
                let texture = 0.8 + 0.35 * hash01(x * 18.0, y * 18.0);
                let light = (self.ambient + self.sun_intensity * self.sun[1].abs().max(0.3))
                    * texture
                    * 255.0;
                self.ground.map(|c| c * light)
            }
        };
        self.put(pixel, rgb);
    }
}
