//! Where the ALACS unit sits relative to the ToF camera: the one transform the simulator uses to
//! place its ALACS and the laser process uses to move perception's rough apple position (ToF
//! colour-camera frame) into the ALACS camera frame before planning a scan ([alacs sec. 3],
//! "Initialization": the rough location is transformed into the ALACS unit's frame).

use harvest_ipc::camera_model::RigidTransform;

/// `cos` and `sin` of the ToF camera's downward pitch in the default mounting: its optical axis
/// runs from robot `(0, 0, 0.9)` m towards `(1.35, 0, 0.3)` m, `atan(0.6 / 1.35)` = 23.96 deg.
const TOF_PITCH_COS: f64 = 0.9138115486202572;
const TOF_PITCH_SIN: f64 = 0.40613846605344767;

/// `cos` and `sin` of the ALACS camera's downward pitch in the design mounting: 5 deg.
const ALACS_PITCH_COS: f64 = 0.9961946980917455;
const ALACS_PITCH_SIN: f64 = 0.08715574274765817;

/// `alacs_from_tof_camera`: maps a point in the ToF camera's colour (RGB) optical frame (the frame
/// perception reports apples in) into the ALACS camera's optical frame. Both frames: x right,
/// y down, z forward, metres.
///
/// Design mounting (the simulated unit's truth; a real robot replaces it with a measured one;
/// the ALACS paper does not say where its unit sits): with the ToF colour sensor at robot
/// `(0, -0.025, 0.9)` m pitched down 23.96 deg (every scenario preset), the ALACS camera sits at
/// robot `(0.30, 0.20, 0.40)` m, looking along robot +x tilted 5 deg down, image x towards
/// robot -y (the slide moves the laser left and right, as in the paper's unit). Chosen from a
/// grid of positions and headings by the share of the apples the arms can pick that the unit can
/// scan (`tools/eval/tests/laser_mounting.rs`, which prints the figures):
/// - the apples the arms pick on the simulated rows lie at robot x 1.27-1.49 m, y -0.29-0.30 m,
///   z 0.02-0.61 m (10th-90th percentiles): about 1.0-1.2 m in front of the camera, inside
///   the 0.6-1.2 m range [alacs sec. 5.2] validated the unit over;
/// - the laser emitter sits `L cos(alpha)` (0.18-0.36 m) left of the camera and the laser
///   crosses to the right ([alacs eq. 4]), so the band of apple centres the 20 cm slide can scan is
///   about 0.23 m wide: at 1.1 m in front of the camera it spans robot y 0.00-0.23 m (the
///   earlier level mount at `(0.30, 0.05, 0.45)` m: -0.15-0.08 m) and its image, tilted 5 deg
///   down from 5 cm lower, now holds the lowest apples the arms pick (the earlier mount missed
///   103 of 423 apples above or below its image, this one 12);
/// - of the apples the arms pick on the rows (seeds 1-5) 37-41 % are in reach, against 19-22 %
///   with the earlier mount; the rest lie beside the band (they spread 0.6 m sideways);
/// - the unit (camera to emitter, up to robot `(0.42, 0.56, 0.39)` m) stays behind and beside
///   the arms' tubes (their axes at least 0.18 m from it on the way to any apple they pick) and
///   below the ToF camera's view.
///
/// In that mounting the rotation is a pitch about the shared x axis by the difference of the two
/// pitches (18.96 deg) and the ToF colour origin is 22.5 cm right of the ALACS camera.
pub const ALACS_FROM_TOF_CAMERA: RigidTransform = {
    // cos and sin of (ToF pitch - ALACS pitch).
    let cos = TOF_PITCH_COS * ALACS_PITCH_COS + TOF_PITCH_SIN * ALACS_PITCH_SIN;
    let sin = TOF_PITCH_SIN * ALACS_PITCH_COS - TOF_PITCH_COS * ALACS_PITCH_SIN;
    // The ToF colour origin minus the ALACS camera's, robot frame: (-0.30, -0.225, 0.50) m,
    // on the ALACS camera's right, down and forward axes.
    RigidTransform {
        rotation: [[1.0, 0.0, 0.0], [0.0, cos, sin], [0.0, -sin, cos]],
        translation_m: [
            0.225,
            0.30 * ALACS_PITCH_SIN - 0.50 * ALACS_PITCH_COS,
            -0.30 * ALACS_PITCH_COS - 0.50 * ALACS_PITCH_SIN,
        ],
    }
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
        let (ca, sa) = (ALACS_PITCH_COS, ALACS_PITCH_SIN);
        assert!((ca * ca + sa * sa - 1.0).abs() < 1e-15);
        assert!((sa.atan2(ca).to_degrees() - 5.0).abs() < 1e-12);
        // ALACS camera: forward (ca, 0, -sa), right -y, down = forward x right.
        let robot_from_alacs = robot_from_camera(
            [0.0, -1.0, 0.0],
            [-sa, 0.0, -ca],
            [ca, 0.0, -sa],
            [0.30, 0.20, 0.40],
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
        // The median apple the arms pick on the simulated rows, robot (1.40, 0.03, 0.31) m, is
        // 1.1 m in front of the ALACS camera, 0.17 m to its right and near the image centre.
        let point_in_robot = [1.40, 0.03, 0.31];
        let in_tof = robot_from_tof.inverse().apply(point_in_robot);
        let in_alacs = ALACS_FROM_TOF_CAMERA.apply(in_tof);
        let want = robot_from_alacs.inverse().apply(point_in_robot);
        for (got, want) in in_alacs.iter().zip(want) {
            assert!((got - want).abs() < 1e-12, "{in_alacs:?}");
        }
        assert!((in_alacs[0] - 0.17).abs() < 1e-12, "{in_alacs:?}");
        assert!((in_alacs[2] - 1.1).abs() < 0.01, "{in_alacs:?}");
        assert!(in_alacs[1].abs() < 0.01, "{in_alacs:?}");
    }
}
