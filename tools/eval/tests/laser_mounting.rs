//! Where the ALACS unit can sit on the robot: for candidate mountings, the share of the apples
//! the arms can pick (ground truth, the simulator's rows and default scenario) that the laser
//! can scan ([`LaserReach`]: in the ALACS image and a scan within the slide's 20 cm stroke),
//! their depth from the ALACS camera ([alacs sec. 5.2] validated 0.6-1.2 m) and how close
//! the arms' tubes come to the unit on their way to those apples.
//!
//! `cargo test --release -p harvest-eval --test laser_mounting -- --nocapture` prints the
//! committed mounting's figures ([`ALACS_FROM_TOF_CAMERA`]) with why the other picked apples are
//! out of reach, and the best candidates of a grid of positions and headings that keep the unit
//! clear of the tubes and out of the ToF camera's view. Ground truth only: which apples the
//! running stack asks to scan is perception's policy (occluded or uncertain apples).
//!
//! Checks: the committed mounting keeps clear of the tubes and out of the ToF camera's view,
//! reaches at least 30 % of the apples the arms pick on the rows within 0.6-1.2 m, and is
//! within 10 points of the best candidate of the grid.

use harvest_field::{StageTravel, choose_offsets};
use harvest_hw::alacs::{ALACS_FROM_TOF_CAMERA, AlacsExtrinsics, alacs_camera_intrinsics};
use harvest_ipc::camera_model::{CameraIntrinsics, RigidTransform};
use harvest_laser::scan::ScanPlanError;
use harvest_laser::{LaserReach, ReachError, ScanConfig};
use harvest_robot_model::clearance::{DEFAULT_CLEARANCE_M, TubeSegment, segment_distance_m};
use harvest_robot_model::joint::JointPosition;
use harvest_robot_model::kinematics::inverse;
use harvest_robot_model::params::ArmParams;
use harvest_sim::alacs_device::robot_from_tof_color;
use harvest_sim::row::RowScenario;
use harvest_sim::{AppleState, Scenario, World};

/// One apple an arm can pick: where the ToF camera sees it and the tube bodies of the arms
/// that can pick it, sampled along the joint path from home to the apple.
#[derive(Clone)]
struct Target {
    centre_in_tof_m: [f64; 3],
    radius_m: f64,
    tubes: Vec<TubeSegment>,
}

/// The apples of one set of stops (a row kind or the default scenario).
struct Case {
    name: String,
    robot_from_tof: RigidTransform,
    /// Apples in reach of an arm at the stops.
    picked: Vec<Target>,
    /// Every apple on the tree in the camera's half-space at the stops (for the default
    /// scenario's `harvest eval laser` figure).
    all: Vec<Target>,
}

fn arms() -> [ArmParams; 2] {
    [ArmParams::arm1(), ArmParams::arm2()]
}

/// The tube segments of `arm` reaching `apple_m` with `other` parked (at least the clearance
/// between them, as `harvest_field::positioning` counts reach), sampled from home to the apple.
fn reaching_tubes(arm: &ArmParams, other: &ArmParams, apple_m: [f64; 3]) -> Vec<TubeSegment> {
    let Ok(q) = inverse(arm, apple_m) else {
        return Vec::new();
    };
    let parked = TubeSegment::at(&other.links, &other.home);
    if segment_distance_m(&TubeSegment::at(&arm.links, &q), &parked) < DEFAULT_CLEARANCE_M {
        return Vec::new();
    }
    let (home, goal) = (arm.home.to_array(), q.to_array());
    (0..=10)
        .map(|k| {
            let s = k as f64 / 10.0;
            let joints = JointPosition::from_array(std::array::from_fn(|i| {
                home[i] + s * (goal[i] - home[i])
            }));
            TubeSegment::at(&arm.links, &joints)
        })
        .collect()
}

fn target(robot_from_tof: &RigidTransform, apple_m: [f64; 3], radius_m: f64) -> Target {
    let [a1, a2] = arms();
    let mut tubes = reaching_tubes(&a1, &a2, apple_m);
    tubes.extend(reaching_tubes(&a2, &a1, apple_m));
    Target {
        centre_in_tof_m: robot_from_tof.inverse().apply(apple_m),
        radius_m,
        tubes,
    }
}

/// The rows of `sim/rows/<name>.toml`, seeds 1-5, one stop per section centre with the platform
/// offsets `choose_offsets` picks from the ground-truth apples (the executive picks them from
/// the detections).
fn row_case(name: &str, text: &str) -> Case {
    let row = RowScenario::from_toml_str(name, text).expect("row");
    let platform = row.file.platform;
    let travel = StageTravel {
        in_out_max_m: platform.in_out_range_m[1] - platform.in_out_range_m[0],
        up_down_max_m: platform.up_down_range_m[1] - platform.up_down_range_m[0],
    };
    let [a1, a2] = arms();
    let mut case = None::<Case>;
    for seed in 1..=5 {
        let mut world = World::generate_row(&row, seed).expect("row world");
        let robot_from_tof = robot_from_tof_color(&world);
        let case = case.get_or_insert_with(|| Case {
            name: format!("row {name} (seeds 1-5)"),
            robot_from_tof,
            picked: Vec::new(),
            all: Vec::new(),
        });
        for section in &row.file.sections {
            world.set_robot_offset_m([0.0, section.center_m, 0.0]);
            let on_tree: Vec<([f64; 3], f64)> = world
                .apples()
                .iter()
                .filter(|apple| apple.state == AppleState::OnTree)
                .map(|apple| (apple.center_in_robot_m, apple.radius_m))
                .collect();
            let centres: Vec<[f64; 3]> = on_tree.iter().map(|(centre, _)| *centre).collect();
            let chosen = choose_offsets([&a1, &a2], &centres, travel, [0.0; 2]).expect("offsets");
            let [in_out, up_down] = chosen.offset_m;
            for (centre, radius_m) in on_tree {
                let moved = [centre[0] - in_out, centre[1], centre[2] - up_down];
                if moved[1].abs() > 1.0 {
                    continue;
                }
                let apple = target(&case.robot_from_tof, moved, radius_m);
                if !apple.tubes.is_empty() {
                    case.picked.push(apple.clone());
                }
                case.all.push(apple);
            }
        }
    }
    case.expect("seeds")
}

/// The default scenario, worlds of seeds 1-30, the robot where the scenario puts it.
fn default_case() -> Case {
    let scenario = Scenario::preset("default").expect("default scenario");
    let mut case = None::<Case>;
    for seed in 1..=30 {
        let world = World::generate(&scenario, seed).expect("world");
        let case = case.get_or_insert_with(|| Case {
            name: "default scenario (seeds 1-30)".to_owned(),
            robot_from_tof: robot_from_tof_color(&world),
            picked: Vec::new(),
            all: Vec::new(),
        });
        for apple in world.apples() {
            let apple = target(
                &case.robot_from_tof,
                apple.center_in_robot_m,
                apple.radius_m,
            );
            if !apple.tubes.is_empty() {
                case.picked.push(apple.clone());
            }
            case.all.push(apple);
        }
    }
    case.expect("seeds")
}

/// A mounting given by the ALACS camera's position in the robot frame and its heading.
#[derive(Debug, Clone, Copy)]
struct Mount {
    position_m: [f64; 3],
    /// Turned towards robot +y (left), deg.
    yaw_deg: f64,
    /// Tilted down, deg.
    pitch_deg: f64,
}

impl Mount {
    /// Columns: the camera's right, down and forward axes in the robot frame.
    fn robot_from_alacs(&self) -> RigidTransform {
        let (sy, cy) = self.yaw_deg.to_radians().sin_cos();
        let (sp, cp) = self.pitch_deg.to_radians().sin_cos();
        let forward = [cp * cy, cp * sy, -sp];
        let right = [sy, -cy, 0.0];
        let down = [
            forward[1] * right[2] - forward[2] * right[1],
            forward[2] * right[0] - forward[0] * right[2],
            forward[0] * right[1] - forward[1] * right[0],
        ];
        RigidTransform {
            rotation: std::array::from_fn(|row| [right[row], down[row], forward[row]]),
            translation_m: self.position_m,
        }
    }
}

/// What one mounting does on one case.
#[derive(Debug, Clone, Copy, Default)]
struct Figures {
    picked: usize,
    picked_in_reach: usize,
    /// Of those in reach, within 0.6-1.2 m of the ALACS camera.
    picked_in_reach_validated_depth: usize,
    all: usize,
    all_in_reach: usize,
    /// Nearest approach of a reaching tube's axis to the unit (camera to the emitter at the
    /// slide's home, the unit's far end), m.
    tube_clearance_m: f64,
    /// Whether some point of the unit shows in the ToF colour camera's image (it would hide
    /// part of the canopy from perception).
    in_tof_view: bool,
}

impl Figures {
    fn picked_share(&self) -> f64 {
        self.picked_in_reach as f64 / self.picked.max(1) as f64
    }
}

fn figures(case: &Case, alacs_from_tof: RigidTransform) -> Figures {
    let extrinsics = AlacsExtrinsics::paper_table1();
    let reach = LaserReach::new(
        extrinsics,
        alacs_camera_intrinsics(),
        alacs_from_tof,
        ScanConfig::default(),
    );
    let robot_from_alacs = case.robot_from_tof.compose(&alacs_from_tof.inverse());
    let unit = TubeSegment {
        pivot_m: robot_from_alacs.translation_m,
        tip_m: robot_from_alacs.apply(extrinsics.camera_from_laser(0.0).translation_m),
    };
    let tof_intrinsics = CameraIntrinsics::tl460_rgb();
    let tof_from_robot = case.robot_from_tof.inverse();
    let in_tof_view = (0..=10).any(|k| {
        let s = k as f64 / 10.0;
        let point =
            std::array::from_fn(|i| unit.pivot_m[i] + s * (unit.tip_m[i] - unit.pivot_m[i]));
        tof_intrinsics
            .project(tof_from_robot.apply(point))
            .is_some_and(|(u, v)| tof_intrinsics.contains(u, v))
    });
    let mut out = Figures {
        picked: case.picked.len(),
        all: case.all.len(),
        tube_clearance_m: f64::INFINITY,
        in_tof_view,
        ..Figures::default()
    };
    for apple in &case.picked {
        if reach.check(apple.centre_in_tof_m, apple.radius_m).is_ok() {
            out.picked_in_reach += 1;
            let depth_m = alacs_from_tof.apply(apple.centre_in_tof_m)[2];
            out.picked_in_reach_validated_depth += usize::from((0.6..=1.2).contains(&depth_m));
        }
        for tube in &apple.tubes {
            out.tube_clearance_m = out.tube_clearance_m.min(segment_distance_m(tube, &unit));
        }
    }
    out.all_in_reach = case
        .all
        .iter()
        .filter(|apple| reach.check(apple.centre_in_tof_m, apple.radius_m).is_ok())
        .count();
    out
}

/// Why the picked apples are out of reach: not in the ALACS image (above, below or beside it)
/// or beyond the stroke (slide needed below 0 or beyond 0.2 m), and where the picked apples lie.
fn diagnose(case: &Case, alacs_from_tof: RigidTransform) {
    let reach = LaserReach::new(
        AlacsExtrinsics::paper_table1(),
        alacs_camera_intrinsics(),
        alacs_from_tof,
        ScanConfig::default(),
    );
    let intrinsics = alacs_camera_intrinsics();
    let mut why = [0usize; 5]; // not in view vertically, sideways, stroke low, stroke high
    let mut robot: [Vec<f64>; 3] = Default::default();
    for apple in &case.picked {
        let p = case.robot_from_tof.apply(apple.centre_in_tof_m);
        for (axis, values) in robot.iter_mut().enumerate() {
            values.push(p[axis]);
        }
        match reach.check(apple.centre_in_tof_m, apple.radius_m) {
            Ok(_) => why[0] += 1,
            Err(ReachError::NotInView {
                centre_in_alacs_m: c,
            }) => {
                let (u, v) = (c[0] / c[2], c[1] / c[2]);
                let (u_edge, v_edge) = (
                    0.5 * intrinsics.width_px as f64 / intrinsics.fx_px,
                    0.5 * intrinsics.height_px as f64 / intrinsics.fy_px,
                );
                why[if v.abs() / v_edge > u.abs() / u_edge {
                    1
                } else {
                    2
                }] += 1;
            }
            Err(ReachError::Plan(ScanPlanError::OutOfReach { first_m, .. })) => {
                why[if first_m < 0.0 { 3 } else { 4 }] += 1;
            }
            Err(ReachError::Plan(_)) => {}
        }
    }
    let quantiles = |values: &mut Vec<f64>| {
        values.sort_by(f64::total_cmp);
        let at = |q: f64| values[((values.len() - 1) as f64 * q).round() as usize];
        format!("{:.2} / {:.2} / {:.2}", at(0.1), at(0.5), at(0.9))
    };
    println!(
        "  {}: in reach {}, out: not in view above or below {}, beside {}; slide needed below 0 {}, beyond the stroke {}; \
picked apples robot x {} , y {} , z {} m (p10 / p50 / p90)",
        case.name,
        why[0],
        why[1],
        why[2],
        why[3],
        why[4],
        quantiles(&mut robot[0]),
        quantiles(&mut robot[1]),
        quantiles(&mut robot[2])
    );
}

fn print(label: &str, case: &Case, f: &Figures) {
    println!(
        "{label}: {}: picked apples in laser reach {} / {} ({:.0} %), {} of them 0.6-1.2 m deep; \
all apples in reach {} / {} ({:.0} %); tube to unit {:.2} m; unit in the ToF camera's view: {}",
        case.name,
        f.picked_in_reach,
        f.picked,
        100.0 * f.picked_share(),
        f.picked_in_reach_validated_depth,
        f.all_in_reach,
        f.all,
        100.0 * f.all_in_reach as f64 / f.all.max(1) as f64,
        f.tube_clearance_m,
        f.in_tof_view
    );
}

/// Nearest approach of the arms' tubes to the unit the analysis accepts: a tube's radius and
/// cup (about 4 cm) plus about half the unit's width and a margin, m.
const UNIT_CLEARANCE_M: f64 = 0.12;

#[test]
fn the_mounting_lets_the_laser_scan_apples_the_arms_pick_on_the_rows() {
    let rows = [
        row_case(
            "two_stops",
            include_str!("../../../sim/rows/two_stops.toml"),
        ),
        row_case(
            "three_sections",
            include_str!("../../../sim/rows/three_sections.toml"),
        ),
    ];
    let default = default_case();
    let robot_from_tof = default.robot_from_tof;
    for case in rows.iter().chain([&default]) {
        assert_eq!(case.robot_from_tof, robot_from_tof, "{}", case.name);
        assert!(!case.picked.is_empty(), "{}", case.name);
    }
    let committed: Vec<Figures> = rows
        .iter()
        .chain([&default])
        .map(|case| {
            let f = figures(case, ALACS_FROM_TOF_CAMERA);
            print("committed", case, &f);
            diagnose(case, ALACS_FROM_TOF_CAMERA);
            f
        })
        .collect();

    // The grid: positions behind the arms' reach, headings from straight ahead.
    let mut scored = Vec::new();
    for x in [0.2, 0.3, 0.4, 0.5] {
        for y_cm in (-30..=60).step_by(5) {
            for z in [0.3, 0.35, 0.4, 0.45, 0.5, 0.55, 0.6, 0.75, 0.9] {
                for yaw_deg in [-20.0, -15.0, -10.0, -5.0, 0.0, 5.0, 10.0, 20.0] {
                    for pitch_deg in [-10.0, 0.0, 5.0, 10.0, 15.0, 20.0, 25.0] {
                        let mount = Mount {
                            position_m: [x, 0.01 * y_cm as f64, z],
                            yaw_deg,
                            pitch_deg,
                        };
                        let alacs_from_tof =
                            mount.robot_from_alacs().inverse().compose(&robot_from_tof);
                        let f: Vec<Figures> = rows
                            .iter()
                            .chain([&default])
                            .map(|case| figures(case, alacs_from_tof))
                            .collect();
                        if f.iter()
                            .any(|f| f.tube_clearance_m < UNIT_CLEARANCE_M || f.in_tof_view)
                        {
                            continue;
                        }
                        let row_picked: usize = f[..2].iter().map(|f| f.picked).sum();
                        let row_in_reach: usize = f[..2].iter().map(|f| f.picked_in_reach).sum();
                        let row_validated: usize = f[..2]
                            .iter()
                            .map(|f| f.picked_in_reach_validated_depth)
                            .sum();
                        scored.push((
                            row_validated as f64 / row_picked as f64,
                            row_in_reach as f64 / row_picked as f64,
                            mount,
                            f,
                        ));
                    }
                }
            }
        }
    }
    scored.sort_by(|a, b| b.0.total_cmp(&a.0));
    for (validated, in_reach, mount, f) in scored.iter().take(25) {
        println!(
            "candidate {mount:?}: rows {:.0} % of picked in reach ({:.0} % also 0.6-1.2 m deep); \
default picked {:.0} %, all {:.0} %; tube to unit {:.2} m",
            100.0 * in_reach,
            100.0 * validated,
            100.0 * f[2].picked_share(),
            100.0 * f[2].all_in_reach as f64 / f[2].all.max(1) as f64,
            f.iter()
                .map(|f| f.tube_clearance_m)
                .fold(f64::INFINITY, f64::min)
        );
    }
    for (validated, in_reach, mount, f) in scored.iter().filter(|c| c.2.yaw_deg == 0.0).take(8) {
        println!(
            "straight ahead {mount:?}: rows {:.0} % ({:.0} % 0.6-1.2 m deep); default picked {:.0} %, all {:.0} %",
            100.0 * in_reach,
            100.0 * validated,
            100.0 * f[2].picked_share(),
            100.0 * f[2].all_in_reach as f64 / f[2].all.max(1) as f64,
        );
    }
    if let Some((_, _, mount, _)) = scored.first() {
        let alacs_from_tof = mount.robot_from_alacs().inverse().compose(&robot_from_tof);
        for case in rows.iter().chain([&default]) {
            diagnose(case, alacs_from_tof);
        }
    }
    let best = scored.first().expect("a candidate clear of the arms").0;
    let row_picked: usize = committed[..2].iter().map(|f| f.picked).sum();
    let row_validated: usize = committed[..2]
        .iter()
        .map(|f| f.picked_in_reach_validated_depth)
        .sum();
    let share = row_validated as f64 / row_picked as f64;
    println!(
        "committed: rows {:.0} % of picked in reach and 0.6-1.2 m deep; best of the grid {:.0} %",
        100.0 * share,
        100.0 * best
    );
    assert!(
        committed
            .iter()
            .all(|f| f.tube_clearance_m >= UNIT_CLEARANCE_M && !f.in_tof_view)
    );
    assert!(share >= 0.30, "{share}");
    assert!(share >= best - 0.10, "{share} vs the grid's best {best}");
}
