//! Rasterisation of a [`Scene`](super::scene::Scene) into one camera's z-buffer, band by band.

use super::camera::{PixelBox, RasterCamera};
use super::dot;
use super::scene::{DiscPrim, Scene};
use super::shader::Shader;

/// Image rows rasterised together: every object is clipped to one band at a time so the band's
/// rays, depths and colours stay in cache while all objects covering it are drawn (objects
/// overlap about three deep, and the RGB ray table alone is 16 MB).
pub(super) const BAND_ROWS: usize = 16;

/// The rows of one band and the buffers they index.
pub(super) struct Band<'a> {
    pub(super) v0: usize,
    pub(super) v1: usize,
    pub(super) width: usize,
    pub(super) rays: &'a [[f32; 2]],
    pub(super) z_m: &'a mut [f32],
}

impl Band<'_> {
    /// Visits `(pixel, ray, depth)` for the part of `area` inside this band.
    #[inline(always)]
    fn for_each(&mut self, area: PixelBox, mut visit: impl FnMut(usize, [f32; 2], &mut f32)) {
        for v in area.v0.max(self.v0)..=area.v1.min(self.v1) {
            let start = v * self.width + area.u0;
            let end = v * self.width + area.u1 + 1;
            let row = self.rays[start..end]
                .iter()
                .zip(self.z_m[start..end].iter_mut());
            for (offset, (ray, z)) in row.enumerate() {
                visit(start + offset, *ray, z);
            }
        }
    }
}

impl Band<'_> {
    /// Draws a leaf into this band. Leaves are the bulk of the work, so each row is tested in
    /// chunks: first a branch-free pass computing which pixels the leaf wins (vectorisable),
    /// then the winners are written and shaded.
    #[inline(always)]
    fn draw_disc<S: Shader>(&mut self, prim: &DiscPrim, shader: &mut S) {
        const CHUNK: usize = 64;
        let (n, al, ac) = (prim.normal, prim.along, prim.across);
        let area = prim.area;
        let mut wins = [false; CHUNK];
        for v in area.v0.max(self.v0)..=area.v1.min(self.v1) {
            let row_start = v * self.width + area.u0;
            let row_end = v * self.width + area.u1 + 1;
            let mut start = row_start;
            while start < row_end {
                let end = (start + CHUNK).min(row_end);
                let rays = &self.rays[start..end];
                let z_m = &mut self.z_m[start..end];
                for ((win, &[x, y]), &z) in wins.iter_mut().zip(rays).zip(z_m.iter()) {
                    let facing = n[0] * x + n[1] * y + n[2];
                    let along = al[0] * x + al[1] * y + al[2];
                    let across = ac[0] * x + ac[1] * y + ac[2];
                    *win = (along * along + across * across <= facing * facing)
                        & (facing > 0.0)
                        & (prim.n_dot_c < z * facing);
                }
                for (offset, ((_, &[x, y]), z)) in wins
                    .iter()
                    .zip(rays)
                    .zip(z_m.iter_mut())
                    .enumerate()
                    .filter(|(_, ((win, _), _))| **win)
                {
                    let facing = n[0] * x + n[1] * y + n[2];
                    let across = ac[0] * x + ac[1] * y + ac[2];
                    *z = prim.n_dot_c / facing;
                    shader.disc(start + offset, prim, across / facing);
                }
                start = end;
            }
        }
    }
}

/// Draws every object of `scene` over what the camera's z-buffer (and the shader's output)
/// already hold.
pub(super) fn rasterize<S: Shader>(camera: &mut RasterCamera, scene: &Scene, shader: &mut S) {
    let (width, height) = (camera.width, camera.height);
    for v0 in (0..height).step_by(BAND_ROWS) {
        let mut band = Band {
            v0,
            v1: band_rows_end(v0, height),
            width,
            rays: &camera.rays,
            z_m: &mut camera.z_m,
        };
        let overlaps = |area: &PixelBox| area.v0 <= band_rows_end(v0, height) && area.v1 >= v0;
        for prim in scene.discs.iter().filter(|p| overlaps(&p.area)) {
            band.draw_disc(prim, shader);
        }
        for prim in scene.spheres.iter().filter(|p| overlaps(&p.area)) {
            let [cx, cy, cz] = prim.center;
            band.for_each(prim.area, |pixel, [x, y], z| {
                let b = x * cx + y * cy + cz;
                let dd = x * x + y * y + 1.0;
                let disc = b * b - dd * prim.c_sq_minus_r_sq;
                if disc < 0.0 {
                    return;
                }
                let t = (b - disc.sqrt()) / dd;
                if t <= 0.0 || t >= *z {
                    return;
                }
                *z = t;
                shader.sphere(pixel, prim, [x * t, y * t, t]);
            });
        }
        for prim in scene.cylinders.iter().filter(|p| overlaps(&p.area)) {
            band.for_each(prim.area, |pixel, [x, y], z| {
                let d = [x, y, 1.0];
                let d_dot_a = dot(d, prim.axis);
                let quad = dot(d, d) - d_dot_a * d_dot_a;
                let half_b = dot(d, prim.w_perp);
                let disc = half_b * half_b - quad * prim.w_perp_sq_minus_r_sq;
                if disc < 0.0 || quad <= 0.0 {
                    return;
                }
                let t = (-half_b - disc.sqrt()) / quad;
                if t <= 0.0 || t >= *z {
                    return;
                }
                let along = t * d_dot_a - prim.start_dot_axis;
                if !(0.0..=prim.length).contains(&along) {
                    return;
                }
                *z = t;
                shader.cylinder(pixel, prim, [x * t, y * t, t], along);
            });
        }
    }
}

/// Last row of the band starting at `v0`.
pub(super) fn band_rows_end(v0: usize, height: usize) -> usize {
    (v0 + BAND_ROWS).min(height) - 1
}
