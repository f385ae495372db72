//! What the ALACS camera looks at, as plain data: apples as spheres, leaves as discs and an
//! optional flat background, all in the ALACS camera frame (metres). The simulator builds one of
//! these from its world and the `world_from_alacs_camera` transform.

use serde::{Deserialize, Serialize};

use harvest_hw::alacs::AlacsError;

/// An apple modelled as a sphere.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AppleSphere {
    pub centre_in_camera_m: [f64; 3],
    pub radius_m: f64,
    /// Albedo (diffuse colour under full light), 8-bit RGB.
    pub rgb: [u8; 3],
}

/// A leaf modelled as a flat disc; it hides what lies behind it from the camera and the laser.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LeafDisc {
    pub centre_in_camera_m: [f64; 3],
    /// Normal of the disc (any length but zero; either side is visible).
    pub normal: [f64; 3],
    pub radius_m: f64,
    /// Albedo, 8-bit RGB.
    pub rgb: [u8; 3],
}

/// The whole scene seen by the ALACS camera.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AlacsScene {
    pub apples: Vec<AppleSphere>,
    pub leaves: Vec<LeafDisc>,
    /// Colour of pixels that hit nothing, and albedo of the background plane when there is one.
    pub background_rgb: [u8; 3],
    /// Depth of a fronto-parallel background plane (canopy, wall) that also catches the laser;
    /// `None` for an empty background at infinity.
    pub background_depth_m: Option<f64>,
    /// Direction towards the (distant) sun in the camera frame; any length but zero.
    pub light_direction: [f64; 3],
    /// Share of the albedo seen on surfaces facing away from the light, in `[0, 1]`.
    pub ambient: f64,
}

impl Default for AlacsScene {
    fn default() -> Self {
        Self {
            apples: Vec::new(),
            leaves: Vec::new(),
            background_rgb: [70, 75, 60],
            background_depth_m: None,
            light_direction: [-0.3, -0.6, -1.0],
            ambient: 0.35,
        }
    }
}

/// Which object a ray hit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SurfaceId {
    Apple(usize),
    Leaf(usize),
    Background,
}

/// The nearest intersection of a ray with the scene.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfaceHit {
    pub surface: SurfaceId,
    /// Ray parameter: `point = origin + t * direction`.
    pub t: f64,
    pub point_in_camera_m: [f64; 3],
    /// Unit surface normal facing the ray origin.
    pub normal: [f64; 3],
    pub albedo_rgb: [u8; 3],
}

/// Rays closer than this to their origin are ignored (self-intersection guard), in ray units.
const MIN_T: f64 = 1e-9;

impl AlacsScene {
    /// Checks every object for finite, physically meaningful values; the error names the
    /// offending field and value.
    pub fn validate(&self) -> Result<(), AlacsError> {
        let invalid = |what: String| Err(AlacsError::InvalidInput { what });
        for (index, apple) in self.apples.iter().enumerate() {
            if !apple.centre_in_camera_m.iter().all(|c| c.is_finite()) {
                return invalid(format!(
                    "apples[{index}].centre_in_camera_m = {:?}",
                    apple.centre_in_camera_m
                ));
            }
            if !(apple.radius_m.is_finite() && apple.radius_m > 0.0) {
                return invalid(format!("apples[{index}].radius_m = {}", apple.radius_m));
            }
        }
        for (index, leaf) in self.leaves.iter().enumerate() {
            if !leaf.centre_in_camera_m.iter().all(|c| c.is_finite()) {
                return invalid(format!(
                    "leaves[{index}].centre_in_camera_m = {:?}",
                    leaf.centre_in_camera_m
                ));
            }
            if !(leaf.normal.iter().all(|c| c.is_finite()) && norm(leaf.normal) > 1e-12) {
                return invalid(format!("leaves[{index}].normal = {:?}", leaf.normal));
            }
            if !(leaf.radius_m.is_finite() && leaf.radius_m > 0.0) {
                return invalid(format!("leaves[{index}].radius_m = {}", leaf.radius_m));
            }
        }
        if let Some(depth_m) = self.background_depth_m
            && !(depth_m.is_finite() && depth_m > 0.0)
        {
            return invalid(format!("background_depth_m = {depth_m}"));
        }
        if !(self.light_direction.iter().all(|c| c.is_finite())
            && norm(self.light_direction) > 1e-12)
        {
            return invalid(format!("light_direction = {:?}", self.light_direction));
        }
        if !(0.0..=1.0).contains(&self.ambient) {
            return invalid(format!("ambient = {}", self.ambient));
        }
        Ok(())
    }

    /// Nearest surface hit by the ray `origin + t * direction`, `t > 0`.
    pub fn ray_cast(&self, origin: [f64; 3], direction: [f64; 3]) -> Option<SurfaceHit> {
        let mut best: Option<(SurfaceId, f64)> = None;
        let mut consider = |surface: SurfaceId, t: Option<f64>| {
            if let Some(t) = t
                && best.is_none_or(|(_, best_t)| t < best_t)
            {
                best = Some((surface, t));
            }
        };
        for (index, apple) in self.apples.iter().enumerate() {
            consider(
                SurfaceId::Apple(index),
                intersect_sphere(origin, direction, apple),
            );
        }
        for (index, leaf) in self.leaves.iter().enumerate() {
            consider(
                SurfaceId::Leaf(index),
                intersect_disc(origin, direction, leaf),
            );
        }
        if let Some(depth_m) = self.background_depth_m
            && direction[2].abs() > 1e-12
        {
            let t = (depth_m - origin[2]) / direction[2];
            consider(SurfaceId::Background, (t > MIN_T).then_some(t));
        }
        let (surface, t) = best?;
        let point = [
            origin[0] + t * direction[0],
            origin[1] + t * direction[1],
            origin[2] + t * direction[2],
        ];
        let (outward, albedo_rgb) = match surface {
            SurfaceId::Apple(index) => {
                let apple = &self.apples[index];
                (sub(point, apple.centre_in_camera_m), apple.rgb)
            }
            SurfaceId::Leaf(index) => (self.leaves[index].normal, self.leaves[index].rgb),
            SurfaceId::Background => ([0.0, 0.0, -1.0], self.background_rgb),
        };
        let mut normal = scale(outward, 1.0 / norm(outward));
        if dot(normal, direction) > 0.0 {
            normal = scale(normal, -1.0);
        }
        Some(SurfaceHit {
            surface,
            t,
            point_in_camera_m: point,
            normal,
            albedo_rgb,
        })
    }

    /// Lambertian brightness factor in `[ambient, 1]` of a surface with unit `normal`.
    pub fn shading(&self, normal: [f64; 3]) -> f64 {
        let light = scale(self.light_direction, 1.0 / norm(self.light_direction));
        self.ambient + (1.0 - self.ambient) * dot(normal, light).max(0.0)
    }
}

fn intersect_sphere(origin: [f64; 3], direction: [f64; 3], apple: &AppleSphere) -> Option<f64> {
    let to_origin = sub(origin, apple.centre_in_camera_m);
    let a = dot(direction, direction);
    let half_b = dot(direction, to_origin);
    let c = dot(to_origin, to_origin) - apple.radius_m * apple.radius_m;
    let discriminant = half_b * half_b - a * c;
    if discriminant < 0.0 {
        return None;
    }
    let root = discriminant.sqrt();
    let near = (-half_b - root) / a;
    if near > MIN_T {
        return Some(near);
    }
    let far = (-half_b + root) / a;
    (far > MIN_T).then_some(far)
}

fn intersect_disc(origin: [f64; 3], direction: [f64; 3], leaf: &LeafDisc) -> Option<f64> {
    let denominator = dot(leaf.normal, direction);
    if denominator.abs() < 1e-12 {
        return None;
    }
    let t = dot(leaf.normal, sub(leaf.centre_in_camera_m, origin)) / denominator;
    if t <= MIN_T {
        return None;
    }
    let point = [
        origin[0] + t * direction[0],
        origin[1] + t * direction[1],
        origin[2] + t * direction[2],
    ];
    let offset = sub(point, leaf.centre_in_camera_m);
    (dot(offset, offset) <= leaf.radius_m * leaf.radius_m).then_some(t)
}

pub(crate) fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

pub(crate) fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

pub(crate) fn scale(a: [f64; 3], factor: f64) -> [f64; 3] {
    [a[0] * factor, a[1] * factor, a[2] * factor]
}

pub(crate) fn norm(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scene() -> AlacsScene {
        AlacsScene {
            apples: vec![AppleSphere {
                centre_in_camera_m: [0.0, 0.0, 1.0],
                radius_m: 0.04,
                rgb: [150, 30, 25],
            }],
            leaves: vec![LeafDisc {
                centre_in_camera_m: [0.05, 0.0, 0.9],
                normal: [0.0, 0.0, 1.0],
                radius_m: 0.03,
                rgb: [50, 110, 40],
            }],
            background_depth_m: Some(2.0),
            ..AlacsScene::default()
        }
    }

    #[test]
    fn rays_hit_the_nearest_object() {
        let scene = scene();
        let apple = scene.ray_cast([0.0; 3], [0.0, 0.0, 1.0]).expect("apple");
        assert_eq!(apple.surface, SurfaceId::Apple(0));
        assert!((apple.t - 0.96).abs() < 1e-12);
        assert!((apple.normal[2] + 1.0).abs() < 1e-12);
        // The leaf at z = 0.9 hides the apple's right flank.
        let leaf = scene
            .ray_cast([0.0; 3], [0.03, 0.0, 1.0])
            .expect("leaf in front");
        assert_eq!(leaf.surface, SurfaceId::Leaf(0));
        assert!((leaf.point_in_camera_m[2] - 0.9).abs() < 1e-12);
        let background = scene.ray_cast([0.0; 3], [-0.2, 0.0, 1.0]).expect("plane");
        assert_eq!(background.surface, SurfaceId::Background);
        assert!((background.point_in_camera_m[2] - 2.0).abs() < 1e-12);
    }

    #[test]
    fn invalid_objects_are_named() {
        let mut scene = scene();
        scene.apples[0].radius_m = f64::NAN;
        let error = scene.validate().expect_err("NaN radius");
        assert!(error.to_string().contains("apples[0].radius_m"), "{error}");
        let mut scene = self::scene();
        scene.leaves[0].normal = [0.0; 3];
        assert!(scene.validate().is_err());
    }
}
