//! The static backdrop (next tree row and ground as planes, sky above with no depth return):
//! hit per viewing ray, rendered once per camera and cached.

use super::camera::RasterCamera;
use super::shader::Shader;
use super::{V3, dot, to_f32};
use crate::orchard::World;
use crate::scenario::{BackgroundConfig, LightingConfig};

/// What the backdrop's appearance depends on besides the (fixed) camera pose.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct BackdropKey {
    pub(super) background: BackgroundConfig,
    pub(super) lighting: LightingConfig,
}

impl BackdropKey {
    pub(super) fn of(world: &World) -> Self {
        Self {
            background: world.scenario().background.clone(),
            lighting: world.scenario().lighting.clone(),
        }
    }
}

/// The backdrop (next row, ground, sky) does not move: it is rendered once per camera and
/// copied in at the start of every frame.
#[derive(Debug, Default)]
pub(super) struct BackdropCache {
    pub(super) key: Option<BackdropKey>,
    pub(super) z_m: Vec<f32>,
    /// RGB8 (colour camera only).
    pub(super) rgb: Vec<u8>,
}

/// Background planes expressed for rays in one camera's frame.
#[derive(Debug, Clone, Copy)]
pub(super) struct Backdrop {
    /// Rows of `robot_from_camera`'s rotation: robot x, y, z of a camera-frame direction.
    pub(super) robot_x: V3,
    pub(super) robot_y: V3,
    pub(super) robot_z: V3,
    pub(super) camera_in_robot: V3,
    pub(super) next_row_x: f32,
    pub(super) next_row_top_z: f32,
    pub(super) ground_z: f32,
}

/// What the background ray hit.
#[derive(Debug, Clone, Copy)]
pub(super) enum BackdropHit {
    Sky,
    /// Next tree row at depth `z`, robot `(y, z)` of the hit.
    NextRow {
        z: f32,
        y: f32,
        height: f32,
    },
    /// Ground at depth `z`, robot `(x, y)` of the hit.
    Ground {
        z: f32,
        x: f32,
        y: f32,
    },
}

impl Backdrop {
    pub(super) fn new(world: &World, camera: &RasterCamera) -> Self {
        let r = camera.robot_from_camera.rotation;
        let b = &world.scenario().background;
        Self {
            robot_x: to_f32(r[0]),
            robot_y: to_f32(r[1]),
            robot_z: to_f32(r[2]),
            camera_in_robot: to_f32(camera.robot_from_camera.translation_m),
            next_row_x: b.next_row_x_m as f32,
            next_row_top_z: b.next_row_top_z_m as f32,
            ground_z: b.ground_z_m as f32,
        }
    }

    #[inline(always)]
    fn hit(&self, ray: [f32; 2]) -> BackdropHit {
        let d = [ray[0], ray[1], 1.0];
        let dx = dot(self.robot_x, d);
        let dz = dot(self.robot_z, d);
        let [tx, ty, tz] = self.camera_in_robot;
        if dx > 1e-6 {
            let t = (self.next_row_x - tx) / dx;
            let height = tz + dz * t;
            if height >= self.ground_z && height <= self.next_row_top_z {
                return BackdropHit::NextRow {
                    z: t,
                    y: ty + dot(self.robot_y, d) * t,
                    height,
                };
            }
        }
        if dz < -1e-6 {
            let t = (self.ground_z - tz) / dz;
            let x = tx + dx * t;
            if x <= self.next_row_x {
                return BackdropHit::Ground {
                    z: t,
                    x,
                    y: ty + dot(self.robot_y, d) * t,
                };
            }
        }
        BackdropHit::Sky
    }
}

/// Intersects every pixel's ray with the backdrop, writing its depth (infinity for sky).
pub(super) fn backdrop_pass<S: Shader>(
    rays: &[[f32; 2]],
    z_m: &mut [f32],
    backdrop: &Backdrop,
    shader: &mut S,
) {
    for (pixel, (z, ray)) in z_m.iter_mut().zip(rays).enumerate() {
        let hit = backdrop.hit(*ray);
        *z = match hit {
            BackdropHit::NextRow { z, .. } | BackdropHit::Ground { z, .. } => z,
            BackdropHit::Sky => f32::INFINITY,
        };
        shader.backdrop(pixel, hit);
    }
}
