//! The depth frame: the z-buffer turned into millimetres with the TL460's noise model
//! (`sigma = 4 mm + 0.0025 z`, 0 outside the working range) and the over-exposed apples' extra
//! noise and dropouts.

use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use rand_distr::StandardNormal;

use super::backdrop::{Backdrop, BackdropKey, backdrop_pass};
use super::raster::rasterize;
use super::scene::glare_weight;
use super::shader::{DepthOnly, DepthOwners};
use super::{RenderError, RgbdRenderer};
use crate::orchard::World;

/// Decorrelates the depth-noise stream from the world's other random streams.
const DEPTH_NOISE_STREAM: u64 = 0xd1b5_4a32_d192_ed03;

impl RgbdRenderer {
    /// Renders the depth frame (row-major, millimetres, 0 = no return) into `depth_out_mm`.
    /// The noise is a function of the world seed and `frame_seq`, so a frame can be reproduced.
    pub fn render_depth(
        &mut self,
        world: &World,
        frame_seq: u64,
        depth_out_mm: &mut [u16],
    ) -> Result<(), RenderError> {
        Self::check_len("depth", &self.depth, 1, depth_out_mm.len())?;
        let key = BackdropKey::of(world);
        let camera = &mut self.depth;
        if camera.backdrop.key.as_ref() != Some(&key) {
            let backdrop = Backdrop::new(world, camera);
            let cache = &mut camera.backdrop;
            cache.z_m.resize(camera.z_m.len(), f32::INFINITY);
            backdrop_pass(&camera.rays, &mut cache.z_m, &backdrop, &mut DepthOnly);
            cache.key = Some(key);
            tracing::debug!("rendered the depth backdrop");
        }
        camera.z_m.copy_from_slice(&camera.backdrop.z_m);
        self.scene
            .prepare(world, &self.depth, self.camera.overexposed_patch_scale);
        if self.scene.glare.is_empty() {
            rasterize(&mut self.depth, &self.scene, &mut DepthOnly);
        } else {
            self.depth_owner.clear();
            self.depth_owner.resize(self.depth.z_m.len(), 0);
            let mut shader = DepthOwners {
                owner: &mut self.depth_owner,
            };
            rasterize(&mut self.depth, &self.scene, &mut shader);
        }
        let mut rng = SmallRng::seed_from_u64(
            world.seed() ^ DEPTH_NOISE_STREAM ^ frame_seq.wrapping_mul(0xa24b_aed4_963e_e407),
        );
        let camera = &self.camera;
        let sigma_const_m = (camera.depth_noise_mm / 1000.0) as f32;
        let sigma_fraction = camera.depth_noise_fraction as f32;
        // Over-exposed apples: extra noise and dropouts on their own pixels, tapering to the
        // highlight disc's edge.
        let width = self.depth.width;
        let gain = camera.overexposed_depth_noise_gain as f32;
        let dropout = camera.overexposed_dropout_probability as f32;
        for glare in &self.scene.glare {
            let a = glare.area;
            for v in a.v0..=a.v1 {
                for u in a.u0..=a.u1 {
                    let pixel = v * width + u;
                    if self.depth_owner.get(pixel) != Some(&glare.label) {
                        continue;
                    }
                    let weight = glare_weight(&glare.disc, self.depth.rays[pixel]);
                    let z = self.depth.z_m[pixel];
                    if weight <= 0.0 || !z.is_finite() {
                        continue;
                    }
                    if rng.random::<f32>() < dropout * weight {
                        self.depth.z_m[pixel] = f32::INFINITY;
                        continue;
                    }
                    let extra_gain = 1.0 + (gain - 1.0) * weight;
                    let extra_sigma = (sigma_const_m + sigma_fraction * z)
                        * (extra_gain * extra_gain - 1.0).sqrt();
                    let noise: f32 = rng.sample(StandardNormal);
                    self.depth.z_m[pixel] = z + extra_sigma * noise;
                }
            }
        }
        let [min_m, max_m] = camera.range_m.map(|r| r as f32);
        for (out, z) in depth_out_mm.iter_mut().zip(&self.depth.z_m) {
            let z = *z;
            *out = if z >= min_m && z <= max_m {
                let noise: f32 = rng.sample(StandardNormal);
                let z_mm = 1000.0 * (z + (sigma_const_m + sigma_fraction * z) * noise);
                // Rounded; 0 is reserved for "no return".
                (z_mm.clamp(1.0, f32::from(u16::MAX)) + 0.5) as u16
            } else {
                0
            };
        }
        tracing::trace!(frame_seq, "rendered depth frame");
        Ok(())
    }
}
