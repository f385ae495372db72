//! The 3D model of the robot: both tube arms on their chain frames (so they move with `/tf`)
//! and the platform, as one `SceneUpdate`.
//!
//! Geometry from Table 1 (`harvest-robot-model`): the prismatic rail over the joint range, the
//! pitch-to-yaw offset `(x1, y1, z1)`, the tube of length `x2`. Display choices (not in the
//! paper): tube diameter 0.09 m, suction cup 0.12 m, a 1.2 x 1.0 x 0.05 m platform plate under
//! the robot origin. Each arm's tube is coloured by its phase.

use crate::arm_frames::params;
use crate::color::{self, Rgba};
use crate::frames;
use crate::geometry::{IDENTITY, pose, quaternion_about, vector};
use foxglove::messages::{
    CubePrimitive, CylinderPrimitive, LinePrimitive, Point3, SceneEntity, SceneUpdate,
    SpherePrimitive, TextPrimitive, Timestamp, line_primitive,
};
use harvest_ipc::ArmId;
use harvest_ipc::payloads::ArmPhase;

/// Tube diameter, m (display choice).
pub const TUBE_DIAMETER_M: f64 = 0.09;
/// Suction cup diameter, m (display choice).
pub const CUP_DIAMETER_M: f64 = 0.12;
/// Platform plate under the robot origin: length (x), width (y), thickness (z), m.
pub const PLATFORM_SIZE_M: [f64; 3] = [1.2, 1.0, 0.05];

/// The colour of a tube in `phase`.
pub fn phase_color(phase: Option<ArmPhase>) -> Rgba {
    match phase {
        Some(ArmPhase::Idle) | None => color::GREY,
        Some(ArmPhase::Approach) => color::BLUE,
        Some(ArmPhase::AttachDetach) => color::ORANGE,
        Some(ArmPhase::Retract) => color::PURPLE,
        Some(ArmPhase::Release) => color::GREEN,
        Some(ArmPhase::Stopped) => color::RED,
    }
}

fn entity(timestamp: Timestamp, frame_id: &str, id: String) -> SceneEntity {
    SceneEntity {
        timestamp: Some(timestamp),
        frame_id: frame_id.to_owned(),
        id,
        frame_locked: true,
        ..SceneEntity::default()
    }
}

fn point(p: [f64; 3]) -> Point3 {
    Point3 {
        x: p[0],
        y: p[1],
        z: p[2],
    }
}

fn line(points: &[[f64; 3]], thickness_m: f64, color: Rgba) -> LinePrimitive {
    LinePrimitive {
        r#type: line_primitive::Type::LineStrip as i32,
        pose: Some(pose([0.0; 3], IDENTITY)),
        thickness: thickness_m,
        scale_invariant: false,
        points: points.iter().copied().map(point).collect(),
        color: Some(color.into()),
        ..LinePrimitive::default()
    }
}

/// The entities of one arm, `phase` colouring its tube.
fn arm_entities(arm: ArmId, phase: Option<ArmPhase>, timestamp: Timestamp) -> Vec<SceneEntity> {
    let arm_params = params(arm);
    let links = arm_params.links;
    let names = frames::arm(arm);
    let label = format!("arm{}", arm.number());
    // The rail the carriage slides on, in the robot frame.
    let rail_start = [
        links.x0_m + arm_params.position_limits.min.d_m,
        links.y0_m,
        links.z0_m,
    ];
    let rail_end = [
        links.x0_m + arm_params.position_limits.max.d_m,
        links.y0_m,
        links.z0_m,
    ];
    let mut rail = entity(timestamp, frames::ROBOT, format!("{label}/rail"));
    rail.lines = vec![line(&[rail_start, rail_end], 0.03, color::DARK_GREY)];
    // The carriage and the pitch-to-yaw offset, on link2 (they pitch together).
    let mut offset = entity(timestamp, names.link2, format!("{label}/shoulder"));
    offset.cubes = vec![CubePrimitive {
        pose: Some(pose([0.0; 3], IDENTITY)),
        size: Some(vector([0.12, 0.08, 0.08])),
        color: Some(color::DARK_GREY.into()),
    }];
    offset.lines = vec![line(
        &[[0.0; 3], [links.x1_m, links.y1_m, links.z1_m]],
        0.04,
        color::DARK_GREY,
    )];
    // The tube along link3's x axis (a cylinder's axis is its z: turn z onto x).
    let z_onto_x = quaternion_about([0.0, 1.0, 0.0], std::f64::consts::FRAC_PI_2);
    let mut tube = entity(timestamp, names.link3, format!("{label}/tube"));
    tube.cylinders = vec![CylinderPrimitive {
        pose: Some(pose([links.x2_m / 2.0, 0.0, 0.0], z_onto_x)),
        size: Some(vector([TUBE_DIAMETER_M, TUBE_DIAMETER_M, links.x2_m])),
        bottom_scale: 1.0,
        top_scale: 1.0,
        color: Some(phase_color(phase).into()),
    }];
    tube.texts = vec![TextPrimitive {
        pose: Some(pose([links.x2_m / 2.0, 0.0, 0.12], IDENTITY)),
        billboard: true,
        font_size: 14.0,
        scale_invariant: true,
        color: Some(color::WHITE.into()),
        text: format!(
            "{label} {}",
            phase.map_or("unknown".to_owned(), |p| format!("{p:?}").to_lowercase())
        ),
    }];
    // The suction cup at the tip.
    let mut cup = entity(timestamp, names.end_effector, format!("{label}/cup"));
    cup.cylinders = vec![CylinderPrimitive {
        pose: Some(pose([0.0; 3], z_onto_x)),
        size: Some(vector([CUP_DIAMETER_M, CUP_DIAMETER_M, 0.04])),
        bottom_scale: 1.0,
        top_scale: 0.7,
        color: Some(color::DARK_GREY.into()),
    }];
    vec![rail, offset, tube, cup]
}

/// The whole robot model, each arm's tube coloured by its phase.
pub fn robot_model(phases: [Option<ArmPhase>; 2], timestamp: Timestamp) -> SceneUpdate {
    let mut platform = entity(timestamp, frames::ROBOT, "platform".to_owned());
    platform.cubes = vec![CubePrimitive {
        pose: Some(pose([0.2, 0.0, -PLATFORM_SIZE_M[2] / 2.0], IDENTITY)),
        size: Some(vector(PLATFORM_SIZE_M)),
        color: Some(color::PLATFORM.into()),
    }];
    let mut origin = entity(timestamp, frames::ROBOT, "robot_origin".to_owned());
    origin.spheres = vec![SpherePrimitive {
        pose: Some(pose([0.0; 3], IDENTITY)),
        size: Some(vector([0.03; 3])),
        color: Some(color::WHITE.into()),
    }];
    let mut entities = vec![platform, origin];
    for arm in ArmId::ALL {
        entities.extend(arm_entities(arm, phases[arm.index()], timestamp));
    }
    SceneUpdate {
        deletions: Vec::new(),
        entities,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn model_hangs_on_the_chain_frames_and_colours_by_phase() {
        let model = robot_model([Some(ArmPhase::Approach), None], Timestamp::new(1, 0));
        let frame_of = |id: &str| {
            model
                .entities
                .iter()
                .find(|entity| entity.id == id)
                .map(|entity| entity.frame_id.as_str())
        };
        assert_eq!(frame_of("arm1/tube"), Some("arm1_link3"));
        assert_eq!(frame_of("arm2/cup"), Some("arm2_end_effector"));
        assert_eq!(frame_of("platform"), Some("robot"));
        let tube = model
            .entities
            .iter()
            .find(|entity| entity.id == "arm1/tube")
            .expect("tube");
        assert_eq!(tube.cylinders[0].color, Some(color::BLUE.into()));
        assert_eq!(tube.cylinders[0].size.expect("size").z, 0.90);
        assert!(model.entities.iter().all(|entity| entity.frame_locked));
    }
}
