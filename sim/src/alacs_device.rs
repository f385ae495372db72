//! The simulated ALACS unit ([alacs sec. 3]): a line laser on a 20 cm slide and a
//! 1440x1080 RGB camera, answering the driver's commands on the `hw/alacs/*` channels.
//!
//! [`AlacsDeviceServer`] owns the device state (slide position, laser) and the unit's *true*
//! extrinsics (paper Table 1, method 4: the simulated ground truth a calibration should recover).
//! For each command it moves the slide (instantly, to the encoder's resolution), switches the
//! laser and, when asked, turns the [`World`] into an [`AlacsScene`] seen from the ALACS camera
//! and renders the image with [`AlacsRenderer`] straight into the loaned answer.
//!
//! Where the unit is: the ALACS camera is rigidly mounted relative to the ToF camera's colour
//! sensor by [`ALACS_FROM_TOF_CAMERA`] (see that constant for the design pose: tilted 5 deg down,
//! 0.30 m ahead of, 0.5 m below and 0.225 m left of the ToF camera, 0.85-1.2 m from the canopy).
//! A scenario that moves the ToF camera moves the ALACS with it, so the laser process's
//! transform stays right.
//!
//! What the scene keeps of the world (documented approximations):
//! - apples on the tree or held by an arm, as spheres; dropped and harvested ones are gone;
//!   albedo = the blush/ground colours mixed by the blush fraction;
//! - leaves as discs of the same area as the world's ellipses;
//! - the next tree row as a fronto-parallel background plane at the depth where the optical axis
//!   meets it; branches, ground and sky are not drawn (the renderer has no cylinders);
//! - objects behind the camera or beyond [`AlacsDeviceConfig::max_depth_m`] are dropped.
//!
//! Rendering cost: [`AlacsRenderer`] tests every object against every pixel's ray, so the image
//! is rendered in horizontal bands of [`BAND_ROWS`] rows, each by a renderer whose camera is the
//! band's rows of the full camera (same focal lengths and distortion, principal point shifted),
//! with only the objects that can matter to that band: those its camera rays can meet, and those
//! that can shadow its laser stripe. The image is the same as one full render (up to the
//! per-band noise draw): a laser ray from the emitter (at `y = 0` in the camera frame, eq. 4) to
//! a lit point lies in the laser plane and keeps `y / z` between 0 and the point's, so an
//! object off the plane or outside the band's `y / z` wedge widened to 0 cannot block it.
//!
//! The server does not simulate the slide's travel time: it answers as soon as the image is
//! rendered. `harvest eval laser` models the travel time separately.

use crate::alacs::{
    AlacsRenderer, AlacsScene, AppleSphere, LaserRenderParams, LeafDisc, RenderStats,
};
use harvest_hw::alacs::{
    ALACS_FROM_TOF_CAMERA, AlacsError, AlacsExtrinsics, AlacsFrameInfo, AlacsUnit, LaserPlane,
    SLIDE_STROKE_M, alacs_camera_intrinsics, check_slide_position,
};
use harvest_ipc::MonotonicClock;
use harvest_ipc::camera_model::{CameraIntrinsics, RigidTransform};
use harvest_ipc::payloads::alacs::ALACS_RGB_BYTES;
use harvest_ipc::payloads::{AlacsCommand, AlacsImage, AlacsStatus};
use serde::{Deserialize, Serialize};

use crate::orchard::{AppleState, World};

/// How the simulated unit behaves.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AlacsDeviceConfig {
    /// The unit's true laser-camera extrinsics (default: [alacs Table 1], method 4).
    pub extrinsics: AlacsExtrinsics,
    /// Laser stripe and sensor noise; `laser_on` is the device's state and the noise seed
    /// advances by one per rendered frame.
    pub render: LaserRenderParams,
    /// Encoder resolution: the slide settles on the request rounded to it, m.
    pub slide_resolution_m: f64,
    /// Objects farther than this from the camera are not drawn, m.
    pub max_depth_m: f64,
}

impl Default for AlacsDeviceConfig {
    fn default() -> Self {
        Self {
            extrinsics: AlacsExtrinsics::paper_table1(),
            render: LaserRenderParams::default(),
            slide_resolution_m: 1e-5,
            max_depth_m: 4.0,
        }
    }
}

/// What the device did with one command (the answer's `status` says the same to the driver).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CommandOutcome {
    /// Slide moved and laser switched; `render` is set when an image was captured.
    Done { render: Option<RenderStats> },
    /// The slide target was outside the stroke or not finite; nothing changed.
    SlideOutOfStroke,
    /// Rendering failed (an unusable scene); the slide and laser did move.
    Fault,
}

/// Rows of one render band (see the module docs); 1080 rows make 36 bands.
pub const BAND_ROWS: usize = 30;

/// One horizontal band of the image and its renderer.
#[derive(Debug)]
struct Band {
    /// First image row of the band.
    first_row: usize,
    renderer: AlacsRenderer,
    /// Range of `u_bar = x / z` of the band's pixel rays.
    u_bar_range: [f64; 2],
    /// Range of `v_bar = y / z` of the band's pixel rays.
    v_bar_range: [f64; 2],
}

impl Band {
    fn new(
        intrinsics: &CameraIntrinsics,
        first_row: usize,
        rows: usize,
    ) -> Result<Self, AlacsError> {
        let band_intrinsics = CameraIntrinsics {
            height_px: rows as u32,
            cy_px: intrinsics.cy_px - first_row as f64,
            ..*intrinsics
        };
        // Pixel rays are monotonic in u and v over the image (mild distortion), so the extremes
        // lie on the band's border pixels.
        let width = intrinsics.width_px as usize;
        let last_row = first_row + rows - 1;
        let border = (0..width)
            .flat_map(|u| [(u, first_row), (u, last_row)])
            .chain((first_row..=last_row).flat_map(|v| [(0, v), (width - 1, v)]));
        let mut u_bar_range = [f64::INFINITY, f64::NEG_INFINITY];
        let mut v_bar_range = [f64::INFINITY, f64::NEG_INFINITY];
        for (u, v) in border {
            let (u_bar, v_bar) = intrinsics.normalize(u as f64, v as f64);
            u_bar_range = [u_bar_range[0].min(u_bar), u_bar_range[1].max(u_bar)];
            v_bar_range = [v_bar_range[0].min(v_bar), v_bar_range[1].max(v_bar)];
        }
        const MARGIN: f64 = 1e-6;
        Ok(Self {
            first_row,
            renderer: AlacsRenderer::new(band_intrinsics)?,
            u_bar_range: [u_bar_range[0] - MARGIN, u_bar_range[1] + MARGIN],
            v_bar_range: [v_bar_range[0] - MARGIN, v_bar_range[1] + MARGIN],
        })
    }

    /// True when an object bounded by the sphere (`centre`, `radius_m`) can matter to the band:
    /// its camera rays can meet it, or it can block the laser on its way to a lit point of the
    /// band (it then touches the laser plane, inside the `y / z` wedge widened to 0).
    fn may_show(&self, centre: [f64; 3], radius_m: f64, plane: &LaserPlane) -> bool {
        let [u_lo, u_hi] = self.u_bar_range;
        let [v_lo, v_hi] = self.v_bar_range;
        let seen = in_wedge(centre[0], centre[2], radius_m, u_lo, u_hi)
            && in_wedge(centre[1], centre[2], radius_m, v_lo, v_hi);
        seen || (plane.signed_distance_m(centre).abs() <= radius_m
            && in_wedge(centre[1], centre[2], radius_m, v_lo.min(0.0), v_hi.max(0.0)))
    }
}

/// True when the sphere meets the wedge `lo <= a / z <= hi` (`a` = x or y): its distance to
/// each bounding plane through the origin, on the outer side, is at most its radius.
fn in_wedge(a: f64, z: f64, radius_m: f64, lo: f64, hi: f64) -> bool {
    (a - lo * z) / (1.0 + lo * lo).sqrt() >= -radius_m
        && (a - hi * z) / (1.0 + hi * hi).sqrt() <= radius_m
}

/// The simulated ALACS device: state, truth and renderer.
#[derive(Debug)]
pub struct AlacsDeviceServer {
    intrinsics: CameraIntrinsics,
    bands: Vec<Band>,
    config: AlacsDeviceConfig,
    slide_position_m: f64,
    laser_on: bool,
    frames_rendered: u64,
    /// The world in the camera frame at the last capture; reused between frames.
    scene: AlacsScene,
    /// The objects of one band; reused between bands and frames.
    band_scene: AlacsScene,
}

impl AlacsDeviceServer {
    /// A unit with the ALACS camera of [`alacs_camera_intrinsics`] (the size the image channel
    /// carries), slide at home, laser off. Fails on unusable extrinsics or resolution.
    pub fn new(config: AlacsDeviceConfig) -> Result<Self, AlacsError> {
        if !config.extrinsics.is_valid() {
            return Err(AlacsError::InvalidInput {
                what: format!("extrinsics = {:?}", config.extrinsics),
            });
        }
        if !(config.slide_resolution_m.is_finite() && config.slide_resolution_m > 0.0) {
            return Err(AlacsError::InvalidInput {
                what: format!("slide_resolution_m = {}", config.slide_resolution_m),
            });
        }
        if !(config.max_depth_m.is_finite() && config.max_depth_m > 0.0) {
            return Err(AlacsError::InvalidInput {
                what: format!("max_depth_m = {}", config.max_depth_m),
            });
        }
        let intrinsics = alacs_camera_intrinsics();
        let height = intrinsics.height_px as usize;
        let bands = (0..height)
            .step_by(BAND_ROWS)
            .map(|first_row| Band::new(&intrinsics, first_row, BAND_ROWS.min(height - first_row)))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Self {
            intrinsics,
            bands,
            config,
            slide_position_m: 0.0,
            laser_on: false,
            frames_rendered: 0,
            scene: AlacsScene::default(),
            band_scene: AlacsScene::default(),
        })
    }

    pub fn config(&self) -> &AlacsDeviceConfig {
        &self.config
    }

    pub fn intrinsics(&self) -> &CameraIntrinsics {
        &self.intrinsics
    }

    pub fn slide_position_m(&self) -> f64 {
        self.slide_position_m
    }

    pub fn laser_on(&self) -> bool {
        self.laser_on
    }

    /// Images rendered so far.
    pub fn frames_rendered(&self) -> u64 {
        self.frames_rendered
    }

    /// The world as the last capture saw it (ALACS camera frame, all objects in depth range).
    pub fn last_scene(&self) -> &AlacsScene {
        &self.scene
    }

    /// Carries out one driver command and writes the whole answer into `out` (loaned shared
    /// memory): `request_seq`, state, status, intrinsics, `header.capture_ns` (the render time on
    /// the stack clock) and, for a capture, the image (`has_image = 1`). Without a capture the
    /// `rgb` bytes are left as they were and `has_image = 0` says so. The header's `msg_seq`
    /// and `publish_ns` are left to the publisher.
    pub fn handle(
        &mut self,
        world: &World,
        command: &AlacsCommand,
        out: &mut AlacsImage,
    ) -> CommandOutcome {
        out.request_seq = command.request_seq;
        out._reserved = 0;
        out.intrinsics = self.intrinsics;
        out.has_image = 0;
        let outcome = if check_slide_position(command.slide_target_m).is_err() {
            tracing::debug!(
                request_seq = command.request_seq,
                slide_target_m = command.slide_target_m,
                "ALACS command refused: slide target outside the stroke"
            );
            CommandOutcome::SlideOutOfStroke
        } else {
            let resolution_m = self.config.slide_resolution_m;
            self.slide_position_m = ((command.slide_target_m / resolution_m).round()
                * resolution_m)
                .clamp(0.0, SLIDE_STROKE_M);
            self.laser_on = command.laser_on != 0;
            if command.capture != 0 {
                match self.capture(world, &mut out.rgb) {
                    Ok(stats) => {
                        out.has_image = 1;
                        CommandOutcome::Done {
                            render: Some(stats),
                        }
                    }
                    Err(error) => {
                        tracing::warn!(%error, "simulated ALACS could not render its image");
                        CommandOutcome::Fault
                    }
                }
            } else {
                CommandOutcome::Done { render: None }
            }
        };
        out.header.capture_ns = MonotonicClock::read_ns();
        out.status.set(match outcome {
            CommandOutcome::Done { .. } => AlacsStatus::Ok,
            CommandOutcome::SlideOutOfStroke => AlacsStatus::SlideOutOfStroke,
            CommandOutcome::Fault => AlacsStatus::DeviceFault,
        });
        out.laser_on = u8::from(self.laser_on);
        out.slide_position_m = self.slide_position_m;
        tracing::trace!(
            request_seq = command.request_seq,
            slide_position_m = self.slide_position_m,
            laser_on = self.laser_on,
            ?outcome,
            "ALACS command handled"
        );
        outcome
    }

    /// Renders the world as the ALACS camera sees it now into `rgb`, band by band.
    fn capture(&mut self, world: &World, rgb: &mut [u8]) -> Result<RenderStats, AlacsError> {
        if rgb.len() != ALACS_RGB_BYTES {
            return Err(AlacsError::BufferSize {
                got_bytes: rgb.len(),
                needed_bytes: ALACS_RGB_BYTES,
                width_px: self.intrinsics.width_px,
                height_px: self.intrinsics.height_px,
            });
        }
        let alacs_from_robot = robot_from_alacs_camera(world).inverse();
        fill_scene(
            world,
            &alacs_from_robot,
            self.config.max_depth_m,
            &mut self.scene,
        );
        let extrinsics = self.config.extrinsics;
        let plane = extrinsics.laser_plane_in_camera(self.slide_position_m);
        let frame_seed = self
            .config
            .render
            .noise_seed
            .wrapping_add(world.seed().wrapping_mul(0x9e37_79b9_7f4a_7c15))
            .wrapping_add(self.frames_rendered.wrapping_mul(0xd1b5_4a32_d192_ed03));
        let row_bytes = self.intrinsics.width_px as usize * 3;
        let mut stats = RenderStats::default();
        for (index, band) in self.bands.iter().enumerate() {
            let band_scene = &mut self.band_scene;
            band_scene.clone_from(&self.scene);
            band_scene
                .apples
                .retain(|apple| band.may_show(apple.centre_in_camera_m, apple.radius_m, &plane));
            band_scene
                .leaves
                .retain(|leaf| band.may_show(leaf.centre_in_camera_m, leaf.radius_m, &plane));
            let params = LaserRenderParams {
                laser_on: self.laser_on,
                noise_seed: frame_seed.wrapping_add(index as u64),
                ..self.config.render
            };
            let start = band.first_row * row_bytes;
            let end = start + band.renderer.image_len();
            let band_stats = band.renderer.render(
                &extrinsics,
                self.slide_position_m,
                band_scene,
                &params,
                &mut rgb[start..end],
            )?;
            stats.lit_crossings += band_stats.lit_crossings;
            stats.shadowed_crossings += band_stats.shadowed_crossings;
        }
        self.frames_rendered += 1;
        Ok(stats)
    }
}

/// Pose of the ToF camera's colour sensor in the robot frame (the frame perception reports
/// apples in), as the simulator's RGB-D renderer places it.
pub fn robot_from_tof_color(world: &World) -> RigidTransform {
    world
        .robot_from_camera()
        .compose(&world.scenario().camera.color_from_depth().inverse())
}

/// Pose of the ALACS camera in the robot frame: the ToF colour sensor's pose composed with the
/// fixed mounting [`ALACS_FROM_TOF_CAMERA`].
pub fn robot_from_alacs_camera(world: &World) -> RigidTransform {
    robot_from_tof_color(world).compose(&ALACS_FROM_TOF_CAMERA.inverse())
}

/// Rebuilds `scene` (ALACS camera frame) from the world: the apples and leaves in front of the
/// camera and within `max_depth_m` (visible or not: one may shadow the laser), the next row as
/// the background plane, the sun and the ambient light.
pub fn fill_scene(
    world: &World,
    alacs_from_robot: &RigidTransform,
    max_depth_m: f64,
    scene: &mut AlacsScene,
) {
    let in_range = |centre: [f64; 3], radius_m: f64| {
        centre[2] + radius_m > 0.0 && centre[2] - radius_m < max_depth_m
    };
    scene.apples.clear();
    for apple in world.apples() {
        if matches!(apple.state, AppleState::Dropped | AppleState::Harvested) {
            continue;
        }
        let centre = alacs_from_robot.apply(apple.center_in_robot_m);
        if !in_range(centre, apple.radius_m) {
            continue;
        }
        let blush = apple.blush_fraction.clamp(0.0, 1.0) as f32;
        let rgb = std::array::from_fn(|k| {
            to_u8(blush * apple.blush_rgb[k] + (1.0 - blush) * apple.ground_rgb[k])
        });
        scene.apples.push(AppleSphere {
            centre_in_camera_m: centre,
            radius_m: apple.radius_m,
            rgb,
        });
    }
    scene.leaves.clear();
    for leaf in world.leaves() {
        let centre = alacs_from_robot.apply(leaf.center_in_robot_m);
        let radius_m = (leaf.half_length_m * leaf.half_width_m).sqrt();
        if radius_m.is_nan() || radius_m <= 0.0 || !in_range(centre, radius_m) {
            continue;
        }
        scene.leaves.push(LeafDisc {
            centre_in_camera_m: centre,
            normal: alacs_from_robot.rotate(leaf.normal_in_robot),
            radius_m,
            rgb: leaf.rgb.map(to_u8),
        });
    }
    let scenario = world.scenario();
    let robot_from_alacs = alacs_from_robot.inverse();
    let axis_in_robot = robot_from_alacs.rotate([0.0, 0.0, 1.0]);
    let next_row_depth_m =
        (scenario.background.next_row_x_m - robot_from_alacs.translation_m[0]) / axis_in_robot[0];
    scene.background_depth_m =
        (axis_in_robot[0] > 0.1 && next_row_depth_m.is_finite() && next_row_depth_m > 0.0)
            .then_some(next_row_depth_m);
    scene.background_rgb = scenario.background.next_row_rgb;
    scene.light_direction = alacs_from_robot.rotate(scenario.lighting.sun_direction_in_robot);
    scene.ambient = scenario.lighting.ambient.clamp(0.0, 1.0);
}

fn to_u8(linear: f32) -> u8 {
    (linear * 255.0).round().clamp(0.0, 255.0) as u8
}

/// An [`AlacsUnit`] that drives an [`AlacsDeviceServer`] in the same process, without IPC: the
/// same command/answer path as the simulator's, for evaluations and tests.
pub struct LocalAlacsUnit<'w> {
    server: AlacsDeviceServer,
    world: &'w World,
    answer: Box<AlacsImage>,
    last_request_seq: u32,
    laser_on: bool,
}

impl<'w> LocalAlacsUnit<'w> {
    pub fn new(server: AlacsDeviceServer, world: &'w World) -> Self {
        Self {
            server,
            world,
            answer: zeroed_image(),
            last_request_seq: 0,
            laser_on: false,
        }
    }

    /// Looks at another world (the device keeps its slide and laser state).
    pub fn set_world(&mut self, world: &'w World) {
        self.world = world;
    }

    pub fn server(&self) -> &AlacsDeviceServer {
        &self.server
    }

    fn exchange(&mut self, slide_target_m: f64, capture: bool) -> CommandOutcome {
        self.last_request_seq = self.last_request_seq.wrapping_add(1);
        let command = AlacsCommand {
            request_seq: self.last_request_seq,
            laser_on: u8::from(self.laser_on),
            capture: u8::from(capture),
            slide_target_m,
            ..AlacsCommand::default()
        };
        self.server.handle(self.world, &command, &mut self.answer)
    }
}

impl AlacsUnit for LocalAlacsUnit<'_> {
    type Error = AlacsError;

    fn intrinsics(&self) -> CameraIntrinsics {
        *self.server.intrinsics()
    }

    fn move_slide(&mut self, slide_position_m: f64) -> Result<f64, AlacsError> {
        check_slide_position(slide_position_m)?;
        self.exchange(slide_position_m, false);
        Ok(self.answer.slide_position_m)
    }

    fn set_laser(&mut self, on: bool) -> Result<(), AlacsError> {
        self.laser_on = on;
        self.exchange(self.server.slide_position_m(), false);
        Ok(())
    }

    fn capture_rgb(&mut self, rgb: &mut [u8]) -> Result<AlacsFrameInfo, AlacsError> {
        let intrinsics = *self.server.intrinsics();
        if rgb.len() != ALACS_RGB_BYTES {
            return Err(AlacsError::BufferSize {
                got_bytes: rgb.len(),
                needed_bytes: ALACS_RGB_BYTES,
                width_px: intrinsics.width_px,
                height_px: intrinsics.height_px,
            });
        }
        match self.exchange(self.server.slide_position_m(), true) {
            CommandOutcome::Done { .. } => {}
            CommandOutcome::SlideOutOfStroke | CommandOutcome::Fault => {
                return Err(AlacsError::Fault {
                    part: harvest_hw::alacs::AlacsPart::Camera,
                    detail: "simulated ALACS could not render its image".into(),
                });
            }
        }
        rgb.copy_from_slice(&self.answer.rgb);
        Ok(AlacsFrameInfo {
            stamp_ns: self.answer.header.capture_ns,
            intrinsics,
            slide_position_m: self.answer.slide_position_m,
            laser_on: self.answer.laser_on != 0,
        })
    }
}

/// A zeroed [`AlacsImage`] on the heap (4.7 MB: too large for the stack).
pub fn zeroed_image() -> Box<AlacsImage> {
    harvest_ipc::payload::boxed_zeroed()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::Scenario;
    use harvest_hw::alacs::conformance;

    fn default_world(seed: u64) -> World {
        let scenario = Scenario::preset("default").expect("preset");
        World::generate(&scenario, seed).expect("world")
    }

    #[test]
    fn alacs_sits_at_its_design_pose_about_a_metre_from_the_canopy() {
        let world = default_world(1);
        let robot_from_alacs = robot_from_alacs_camera(&world);
        for (got, want) in robot_from_alacs
            .translation_m
            .iter()
            .zip([0.30, 0.20, 0.40])
        {
            assert!((got - want).abs() < 1e-9, "{:?}", robot_from_alacs);
        }
        let forward = robot_from_alacs.rotate([0.0, 0.0, 1.0]);
        let right = robot_from_alacs.rotate([1.0, 0.0, 0.0]);
        let (sin, cos) = 5.0_f64.to_radians().sin_cos();
        for (got, want) in forward.iter().zip([cos, 0.0, -sin]) {
            assert!((got - want).abs() < 1e-9, "{forward:?}");
        }
        assert!((right[1] + 1.0).abs() < 1e-9, "{right:?}");
        let front_x_m = world.scenario().canopy.front_x_m;
        assert!((front_x_m - robot_from_alacs.translation_m[0] - 0.85).abs() < 1e-9);
    }

    #[test]
    fn scene_holds_the_visible_apples_in_the_camera_frame() {
        let world = default_world(3);
        let intrinsics = alacs_camera_intrinsics();
        let alacs_from_robot = robot_from_alacs_camera(&world).inverse();
        let mut scene = AlacsScene::default();
        fill_scene(&world, &alacs_from_robot, 4.0, &mut scene);
        scene.validate().expect("valid scene");
        let in_view = world
            .apples()
            .iter()
            .filter(|apple| {
                let centre = alacs_from_robot.apply(apple.center_in_robot_m);
                intrinsics
                    .project(centre)
                    .is_some_and(|(u, v)| intrinsics.contains(u, v))
            })
            .count();
        assert!(in_view > 0, "no apple in view of the ALACS");
        // Every apple in front of the camera within the depth range is kept.
        assert!(scene.apples.len() >= in_view);
        assert_eq!(scene.apples.len(), world.apples().len());
        assert!(
            scene
                .background_depth_m
                .is_some_and(|d| (d - 2.9 / 5.0_f64.to_radians().cos()).abs() < 1e-9)
        );
    }

    #[test]
    fn answers_carry_the_request_and_refuse_targets_outside_the_stroke() {
        let world = default_world(1);
        let mut server = AlacsDeviceServer::new(AlacsDeviceConfig::default()).expect("server");
        let mut out = zeroed_image();
        let command = AlacsCommand {
            request_seq: 7,
            laser_on: 1,
            capture: 0,
            slide_target_m: 0.0512345,
            ..AlacsCommand::default()
        };
        let outcome = server.handle(&world, &command, &mut out);
        assert_eq!(outcome, CommandOutcome::Done { render: None });
        assert_eq!(
            (
                out.request_seq,
                out.status.get(),
                out.has_image,
                out.laser_on
            ),
            (7, Ok(AlacsStatus::Ok), 0, 1)
        );
        assert!((out.slide_position_m - 0.05123).abs() < 1e-12);
        let refused = AlacsCommand {
            request_seq: 8,
            laser_on: 0,
            slide_target_m: 0.25,
            ..command
        };
        assert_eq!(
            server.handle(&world, &refused, &mut out),
            CommandOutcome::SlideOutOfStroke
        );
        assert_eq!(
            (out.request_seq, out.status.get(), out.laser_on),
            (8, Ok(AlacsStatus::SlideOutOfStroke), 1)
        );
        assert!((out.slide_position_m - 0.05123).abs() < 1e-12);
    }

    #[test]
    fn banded_render_equals_one_full_render() {
        let world = default_world(4);
        let config = AlacsDeviceConfig {
            render: LaserRenderParams {
                noise_sigma_dn: 0.0,
                ..LaserRenderParams::default()
            },
            ..AlacsDeviceConfig::default()
        };
        let mut server = AlacsDeviceServer::new(config).expect("server");
        let mut out = zeroed_image();
        let command = AlacsCommand {
            request_seq: 1,
            laser_on: 1,
            capture: 1,
            slide_target_m: 0.07,
            ..AlacsCommand::default()
        };
        let CommandOutcome::Done {
            render: Some(banded),
        } = server.handle(&world, &command, &mut out)
        else {
            panic!("capture failed");
        };
        let renderer = AlacsRenderer::new(alacs_camera_intrinsics()).expect("renderer");
        let mut full = vec![0; renderer.image_len()];
        let params = LaserRenderParams {
            laser_on: true,
            ..config.render
        };
        let stats = renderer
            .render(
                &config.extrinsics,
                0.07,
                server.last_scene(),
                &params,
                &mut full,
            )
            .expect("full render");
        assert!(stats.lit_crossings > 0, "{stats:?}");
        assert_eq!(banded, stats);
        let differing = full
            .iter()
            .zip(out.rgb.iter())
            .filter(|(a, b)| a != b)
            .count();
        assert_eq!(differing, 0);
    }

    #[test]
    fn bands_keep_objects_that_shadow_their_stripe_from_outside_the_view() {
        let intrinsics = alacs_camera_intrinsics();
        let extrinsics = AlacsExtrinsics::paper_table1();
        let slide_position_m = 0.05;
        let plane = extrinsics.laser_plane_in_camera(slide_position_m);
        // A lit point on the plane 0.9 m ahead, 10 cm below the axis, and a leaf a quarter of
        // the way from the emitter to it: far left of the camera's view.
        let depth_m = 0.9;
        let (sin_a, cos_a) = extrinsics.alpha_rad.sin_cos();
        let y_m = 0.1;
        let x_m = (depth_m * sin_a
            - extrinsics.beta_rad.tan() * y_m
            - extrinsics.baseline_m(slide_position_m))
            / cos_a;
        let lit = [x_m, y_m, depth_m];
        assert!(plane.signed_distance_m(lit).abs() < 1e-12);
        let emitter = extrinsics.camera_from_laser(slide_position_m).translation_m;
        let leaf: [f64; 3] = std::array::from_fn(|k| emitter[k] + 0.25 * (lit[k] - emitter[k]));
        let (_, v_px) = intrinsics.project(lit).expect("visible");
        let first_row = (v_px as usize / BAND_ROWS) * BAND_ROWS;
        let band = Band::new(&intrinsics, first_row, BAND_ROWS).expect("band");
        assert!(
            intrinsics
                .project(leaf)
                .is_none_or(|(u, v)| !intrinsics.contains(u, v))
        );
        assert!(band.may_show(leaf, 0.01, &plane));
        // Off the plane by more than its radius, the same leaf cannot matter to the band.
        let off_plane = [leaf[0] + 0.05, leaf[1], leaf[2]];
        assert!(!band.may_show(off_plane, 0.01, &plane));
        // A band far above the axis does not need a leaf below it.
        let top = Band::new(&intrinsics, 0, BAND_ROWS).expect("band");
        assert!(!top.may_show([0.0, 0.2, 0.9], 0.02, &plane));
        let top_v_bar = 0.5 * (top.v_bar_range[0] + top.v_bar_range[1]);
        assert!(top.may_show([0.0, top_v_bar * 0.9, 0.9], 0.001, &plane));
    }

    #[test]
    fn local_unit_conforms() {
        let world = default_world(2);
        let server = AlacsDeviceServer::new(AlacsDeviceConfig::default()).expect("server");
        let mut unit = LocalAlacsUnit::new(server, &world);
        conformance::check_all(&mut unit).expect("conformance");
        assert!(unit.server().frames_rendered() >= 3);
    }
}
