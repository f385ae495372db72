//! Where the ALACS unit sits relative to the ToF camera: the one transform the simulator uses to
//! place its ALACS and the laser process uses to move perception's rough apple position (ToF
//! colour-camera frame) into the ALACS camera frame before planning a scan (paper 000, section 3,
//! "Initialization": the rough location is transformed into the ALACS unit's frame).

use harvest_ipc::camera_model::RigidTransform;

/// `cos` and `sin` of the ToF camera's downward pitch in the default mounting: its optical axis
/// runs from robot `(0, 0, 0.9)` m towards `(1.35, 0, 0.3)` m, `atan(0.6 / 1.35)` = 23.96 deg.
const TOF_PITCH_COS: f64 = 0.9138115486202572;
const TOF_PITCH_SIN: f64 = 0.40613846605344767;

/// `alacs_from_tof_camera`: maps a point in the ToF camera's colour (RGB) optical frame (the frame
/// perception reports apples in) into the ALACS camera's optical frame. Both frames: x right,
/// y down, z forward, metres.
///
/// Design mounting (the simulated unit's truth; a real robot replaces it with a measured one):
/// the ALACS hangs on the ToF camera's bracket, level and looking straight at the canopy. With
/// the ToF colour sensor at robot `(0, -0.025, 0.9)` m pitched down 23.96 deg (the default
/// scenario), the ALACS camera sits at robot `(0.30, 0.05, 0.45)` m with its optical axis along
/// robot +x and image x towards robot -y. Rationale:
/// - apples on the canopy (robot x 1.15-1.45 m) are 0.85-1.15 m from the ALACS camera, inside
///   the 0.6-1.2 m range the paper validated the unit over (section 5.2);
/// - the laser emitter sits `L cos(alpha)` (0.18-0.36 m) left of the camera (eq. 4), so the
///   band the 20 cm slide can sweep at about 1 m depth is centred near robot y = 0, in front
///   of the arms.
///
/// In that mounting the rotation is a pitch about the shared x axis and the ToF colour origin is
/// 7.5 cm right, 45 cm above and 30 cm behind the ALACS camera.
pub const ALACS_FROM_TOF_CAMERA: RigidTransform = RigidTransform {
    rotation: [
        [1.0, 0.0, 0.0],
        [0.0, TOF_PITCH_COS, TOF_PITCH_SIN],
        [0.0, -TOF_PITCH_SIN, TOF_PITCH_COS],
    ],
    translation_m: [0.075, -0.45, -0.30],
};

#[cfg(test)]
mod tests {
    use super::*;

    /// Rows are the camera axes (right, down, forward) in the robot frame transposed: the
    /// `robot_from_camera` rotation has them as columns.
    fn robot_from_camera(
        right: [f64; 3],
        down: [f64; 3],
        forward: [f64; 3],
        position_m: [f64; 3],
    ) -> RigidTransform {
        RigidTransform {
            rotation: [
                [right[0], down[0], forward[0]],
                [right[1], down[1], forward[1]],
                [right[2], down[2], forward[2]],
            ],
            translation_m: position_m,
        }
    }

    #[test]
    fn mounting_matches_the_documented_robot_poses() {
        let (c, s) = (TOF_PITCH_COS, TOF_PITCH_SIN);
        assert!((c * c + s * s - 1.0).abs() < 1e-15);
        assert!((s / c - 0.6 / 1.35).abs() < 1e-15);
        // ToF colour sensor: forward (c, 0, -s), right -y, down = forward x right.
        let robot_from_tof = robot_from_camera(
            [0.0, -1.0, 0.0],
            [-s, 0.0, -c],
            [c, 0.0, -s],
            [0.0, -0.025, 0.9],
        );
        let robot_from_alacs = robot_from_camera(
            [0.0, -1.0, 0.0],
            [0.0, 0.0, -1.0],
            [1.0, 0.0, 0.0],
            [0.30, 0.05, 0.45],
        );
        let expected = robot_from_alacs.inverse().compose(&robot_from_tof);
        for (got_row, want_row) in ALACS_FROM_TOF_CAMERA
            .rotation
            .iter()
            .zip(expected.rotation.iter())
        {
            for (got, want) in got_row.iter().zip(want_row) {
                assert!((got - want).abs() < 1e-12, "{got} vs {want}");
            }
        }
        for (got, want) in ALACS_FROM_TOF_CAMERA
            .translation_m
            .iter()
            .zip(expected.translation_m)
        {
            assert!((got - want).abs() < 1e-12, "{got} vs {want}");
        }
        // A canopy point 1.3 m ahead of the robot on its centre line is about 1 m in front of
        // the ALACS camera.
        let point_in_robot = [1.3, 0.0, 0.45];
        let in_tof = robot_from_tof.inverse().apply(point_in_robot);
        let in_alacs = ALACS_FROM_TOF_CAMERA.apply(in_tof);
        assert!((in_alacs[2] - 1.0).abs() < 1e-12, "{in_alacs:?}");
        assert!((in_alacs[0] - 0.05).abs() < 1e-12, "{in_alacs:?}");
        assert!(in_alacs[1].abs() < 1e-12, "{in_alacs:?}");
    }
}
