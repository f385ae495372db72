//! One arm's state as Foxglove sees it: the transforms down its kinematic chain (eq. 1, frames
//! in [`crate::frames`]) and its joints for plots.

use crate::frames;
use crate::geometry::{IDENTITY, frame_transform, quaternion_about, rigid};
use crate::stamps::TimeBase;
use foxglove::messages::{FrameTransform, FrameTransforms, JointState, JointStates};
use harvest_ipc::ArmId;
use harvest_ipc::camera_model::RigidTransform;
use harvest_ipc::payloads::ArmState;
use harvest_robot_model::joint::JointPosition;
use harvest_robot_model::params::{ArmParams, LinkParams};

/// Joint names in `/armN/joints`, in `[D, theta, phi, twist]` order.
pub const JOINT_NAMES: [&str; 4] = ["d_m", "theta_rad", "phi_rad", "twist_rad"];

/// Table 1 parameters of `arm`.
pub fn params(arm: ArmId) -> ArmParams {
    ArmParams::for_arm(arm)
}

/// `parent_from_child` of the four chain links at `q`: robot <- link1 <- link2 <- link3 <- end
/// effector (see [`crate::frames`]).
pub fn chain(links: &LinkParams, q: &JointPosition) -> [RigidTransform; 4] {
    let y_axis = [0.0, 1.0, 0.0];
    let z_axis = [0.0, 0.0, 1.0];
    let x_axis = [1.0, 0.0, 0.0];
    [
        rigid([links.x0_m + q.d_m, links.y0_m, links.z0_m], &IDENTITY),
        rigid([0.0; 3], &quaternion_about(y_axis, -q.theta_rad)),
        rigid(
            [links.x1_m, links.y1_m, links.z1_m],
            &quaternion_about(z_axis, -q.phi_rad),
        ),
        rigid(
            [links.x2_m, 0.0, 0.0],
            &quaternion_about(x_axis, q.twist_rad),
        ),
    ]
}

/// The chain transforms of one arm state, stamped at its capture time.
pub fn arm_transforms(arm: ArmId, state: &ArmState, time: &TimeBase) -> FrameTransforms {
    let q = JointPosition::from_array(state.joint_position);
    let names = frames::arm(arm);
    let parents = [frames::ROBOT, names.link1, names.link2, names.link3];
    let children = [names.link1, names.link2, names.link3, names.end_effector];
    let timestamp = time.timestamp(state.header.capture_ns);
    let transforms: Vec<FrameTransform> = chain(&params(arm).links, &q)
        .iter()
        .zip(parents.iter().zip(children))
        .map(|(transform, (parent, child))| frame_transform(timestamp, parent, child, transform))
        .collect();
    FrameTransforms { transforms }
}

/// The joints of one arm state (encoder feedback: positions and velocities).
pub fn arm_joints(state: &ArmState, time: &TimeBase) -> JointStates {
    JointStates {
        timestamp: Some(time.timestamp(state.header.capture_ns)),
        joints: JOINT_NAMES
            .iter()
            .enumerate()
            .map(|(index, name)| JointState {
                name: (*name).to_owned(),
                position: Some(state.joint_position[index]),
                velocity: Some(state.joint_velocity[index]),
                acceleration: None,
                effort: None,
            })
            .collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::rigid;
    use harvest_robot_model::kinematics;

    fn compose(chain: &[RigidTransform]) -> Vec<RigidTransform> {
        let mut out = Vec::new();
        let mut total = RigidTransform::IDENTITY;
        for link in chain {
            total = total.compose(link);
            out.push(total);
        }
        out
    }

    /// The published chain agrees with eq. 1: its end-effector frame sits at `forward(q)` and
    /// its tube root at the yaw pivot, for both arms over the joint ranges; the tube runs along
    /// link3's x axis.
    #[test]
    fn chain_matches_eq_1() {
        for arm in ArmId::ALL {
            let arm_params = params(arm);
            let (lo, hi) = (
                arm_params.position_limits.min.to_array(),
                arm_params.position_limits.max.to_array(),
            );
            for step in 0..=10 {
                let t = f64::from(step) / 10.0;
                let q = JointPosition::from_array(std::array::from_fn(|i| {
                    let u = if i % 2 == 0 { t } else { 1.0 - t };
                    lo[i] + u * (hi[i] - lo[i])
                }));
                let robot_from = compose(&chain(&arm_params.links, &q));
                let tip = robot_from[3].apply([0.0; 3]);
                let expected = kinematics::forward(&arm_params.links, &q);
                let pivot = robot_from[2].apply([0.0; 3]);
                let expected_pivot = kinematics::yaw_pivot(&arm_params.links, &q);
                for axis in 0..3 {
                    assert!((tip[axis] - expected[axis]).abs() < 1e-12, "{arm:?} {q:?}");
                    assert!((pivot[axis] - expected_pivot[axis]).abs() < 1e-12);
                }
                let along_tube = robot_from[2].apply([arm_params.links.x2_m, 0.0, 0.0]);
                for axis in 0..3 {
                    assert!((along_tube[axis] - expected[axis]).abs() < 1e-12);
                }
            }
        }
    }

    #[test]
    fn transforms_and_joints_of_a_state() {
        let mut state = ArmState::default();
        state.header.capture_ns = 7_000_000_123;
        state.joint_position = [0.3, 0.2, -0.1, 1.0];
        state.joint_velocity = [0.1, 0.0, 0.0, 0.0];
        let transforms = arm_transforms(ArmId::Arm2, &state, &TimeBase::MONOTONIC);
        let pairs: Vec<(&str, &str)> = transforms
            .transforms
            .iter()
            .map(|t| (t.parent_frame_id.as_str(), t.child_frame_id.as_str()))
            .collect();
        assert_eq!(
            pairs,
            [
                ("robot", "arm2_link1"),
                ("arm2_link1", "arm2_link2"),
                ("arm2_link2", "arm2_link3"),
                ("arm2_link3", "arm2_end_effector"),
            ]
        );
        // Recomposed from the messages themselves (translation + quaternion).
        let mut total = RigidTransform::IDENTITY;
        for transform in &transforms.transforms {
            let t = transform.translation.expect("translation");
            let link = rigid([t.x, t.y, t.z], &transform.rotation.expect("rotation"));
            total = total.compose(&link);
        }
        let expected = kinematics::forward(
            &ArmParams::arm2().links,
            &JointPosition::from_array(state.joint_position),
        );
        let tip = total.apply([0.0; 3]);
        for axis in 0..3 {
            assert!((tip[axis] - expected[axis]).abs() < 1e-12);
        }
        let joints = arm_joints(&state, &TimeBase::MONOTONIC);
        assert_eq!(joints.joints[0].name, "d_m");
        assert_eq!(joints.joints[0].position, Some(0.3));
        assert_eq!(joints.joints[0].velocity, Some(0.1));
        assert_eq!(joints.timestamp.expect("stamp").nsec(), 123);
    }
}
