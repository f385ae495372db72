//! Rigid transforms and poses in Foxglove's message types.

use foxglove::messages::{FrameTransform, Pose, Quaternion, Timestamp, Vector3};
use harvest_ipc::camera_model::RigidTransform;

/// The unit quaternion of a proper rotation matrix (row-major), Shepperd's method.
pub fn quaternion_of(rotation: &[[f64; 3]; 3]) -> Quaternion {
    let r = rotation;
    let trace = r[0][0] + r[1][1] + r[2][2];
    let (x, y, z, w) = if trace > 0.0 {
        let s = (trace + 1.0).sqrt() * 2.0;
        (
            (r[2][1] - r[1][2]) / s,
            (r[0][2] - r[2][0]) / s,
            (r[1][0] - r[0][1]) / s,
            0.25 * s,
        )
    } else if r[0][0] > r[1][1] && r[0][0] > r[2][2] {
        let s = (1.0 + r[0][0] - r[1][1] - r[2][2]).sqrt() * 2.0;
        (
            0.25 * s,
            (r[0][1] + r[1][0]) / s,
            (r[0][2] + r[2][0]) / s,
            (r[2][1] - r[1][2]) / s,
        )
    } else if r[1][1] > r[2][2] {
        let s = (1.0 + r[1][1] - r[0][0] - r[2][2]).sqrt() * 2.0;
        (
            (r[0][1] + r[1][0]) / s,
            0.25 * s,
            (r[1][2] + r[2][1]) / s,
            (r[0][2] - r[2][0]) / s,
        )
    } else {
        let s = (1.0 + r[2][2] - r[0][0] - r[1][1]).sqrt() * 2.0;
        (
            (r[0][2] + r[2][0]) / s,
            (r[1][2] + r[2][1]) / s,
            0.25 * s,
            (r[1][0] - r[0][1]) / s,
        )
    };
    let norm = (x * x + y * y + z * z + w * w).sqrt();
    Quaternion {
        x: x / norm,
        y: y / norm,
        z: z / norm,
        w: w / norm,
    }
}

/// The rotation of `angle_rad` about a unit `axis`.
pub fn quaternion_about(axis: [f64; 3], angle_rad: f64) -> Quaternion {
    let (s, c) = (angle_rad / 2.0).sin_cos();
    Quaternion {
        x: axis[0] * s,
        y: axis[1] * s,
        z: axis[2] * s,
        w: c,
    }
}

/// The identity rotation.
pub const IDENTITY: Quaternion = Quaternion {
    x: 0.0,
    y: 0.0,
    z: 0.0,
    w: 1.0,
};

pub fn vector(v: [f64; 3]) -> Vector3 {
    Vector3 {
        x: v[0],
        y: v[1],
        z: v[2],
    }
}

/// A pose at `position` (m) with `orientation`.
pub fn pose(position: [f64; 3], orientation: Quaternion) -> Pose {
    Pose {
        position: Some(vector(position)),
        orientation: Some(orientation),
    }
}

/// The transform placing `child` in `parent`: `parent_from_child` maps child coordinates into
/// the parent's (the rerun / our `target_from_source` naming).
pub fn frame_transform(
    timestamp: Timestamp,
    parent: &str,
    child: &str,
    parent_from_child: &RigidTransform,
) -> FrameTransform {
    FrameTransform {
        timestamp: Some(timestamp),
        parent_frame_id: parent.to_owned(),
        child_frame_id: child.to_owned(),
        translation: Some(vector(parent_from_child.translation_m)),
        rotation: Some(quaternion_of(&parent_from_child.rotation)),
    }
}

/// The rotation matrix of a unit quaternion (row-major).
pub fn rotation_of(q: &Quaternion) -> [[f64; 3]; 3] {
    let (x, y, z, w) = (q.x, q.y, q.z, q.w);
    [
        [
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y - z * w),
            2.0 * (x * z + y * w),
        ],
        [
            2.0 * (x * y + z * w),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z - x * w),
        ],
        [
            2.0 * (x * z - y * w),
            2.0 * (y * z + x * w),
            1.0 - 2.0 * (x * x + y * y),
        ],
    ]
}

/// A rigid transform from a translation (m) and a unit quaternion.
pub fn rigid(translation_m: [f64; 3], rotation: &Quaternion) -> RigidTransform {
    RigidTransform {
        rotation: rotation_of(rotation),
        translation_m,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quaternions_round_trip_through_every_branch() {
        let cases = [
            RigidTransform::from_rpy_translation(0.1, 0.2, 0.3, [0.0; 3]),
            RigidTransform::from_rpy_translation(3.0, 0.1, 0.0, [0.0; 3]),
            RigidTransform::from_rpy_translation(0.0, 3.0, 0.2, [0.0; 3]),
            RigidTransform::from_rpy_translation(0.1, 0.0, 3.1, [0.0; 3]),
            RigidTransform::IDENTITY,
        ];
        for transform in cases {
            let q = quaternion_of(&transform.rotation);
            let norm = q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w;
            assert!((norm - 1.0).abs() < 1e-12);
            let back = rotation_of(&q);
            for (row, expected) in back.iter().zip(&transform.rotation) {
                for (value, expected) in row.iter().zip(expected) {
                    assert!(
                        (value - expected).abs() < 1e-12,
                        "{back:?} vs {transform:?}"
                    );
                }
            }
        }
        // A rotation about z by +90 degrees takes x to y.
        let q = quaternion_about([0.0, 0.0, 1.0], std::f64::consts::FRAC_PI_2);
        let moved = rigid([0.0; 3], &q).apply([1.0, 0.0, 0.0]);
        assert!((moved[1] - 1.0).abs() < 1e-12 && moved[0].abs() < 1e-12);
    }
}
