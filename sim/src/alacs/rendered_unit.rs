//! An ALACS unit living in the process: it renders a fixed [`AlacsScene`] with
//! [`AlacsRenderer`] whenever an image is captured. For tests and offline scan runs; the
//! simulator's unit renders the same way from its own world.

use harvest_ipc::camera_model::CameraIntrinsics;
use serde::{Deserialize, Serialize};

use crate::alacs::render::{AlacsRenderer, LaserRenderParams};
use crate::alacs::scene::AlacsScene;
use harvest_hw::alacs::AlacsError;
use harvest_hw::alacs::extrinsics::{AlacsExtrinsics, check_slide_position};
use harvest_hw::alacs::{AlacsFrameInfo, AlacsUnit};

/// Behaviour of a [`RenderedAlacs`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RenderedAlacsConfig {
    /// The unit's true extrinsics (what calibration should recover).
    pub extrinsics: AlacsExtrinsics,
    /// Laser and sensor appearance; `laser_on` is overridden by [`AlacsUnit::set_laser`] and
    /// the noise seed advances by one per frame.
    pub render: LaserRenderParams,
    /// Encoder resolution: the reported (and true) position is the request rounded to it, m.
    pub slide_resolution_m: f64,
    /// Simulated time between captures; frame `k` is stamped `k * frame_period_ns`.
    pub frame_period_ns: u64,
}

impl Default for RenderedAlacsConfig {
    fn default() -> Self {
        Self {
            extrinsics: AlacsExtrinsics::paper_table1(),
            render: LaserRenderParams::default(),
            slide_resolution_m: 1e-5,
            frame_period_ns: 100_000_000,
        }
    }
}

/// In-process ALACS unit rendering a fixed scene.
#[derive(Debug, Clone)]
pub struct RenderedAlacs {
    renderer: AlacsRenderer,
    config: RenderedAlacsConfig,
    scene: AlacsScene,
    slide_position_m: f64,
    laser_on: bool,
    frames_captured: u64,
}

impl RenderedAlacs {
    /// A unit with the slide at home (`d = 0`) and the laser off. Fails with kind
    /// `InvalidRequest` on unusable intrinsics, extrinsics, resolution or scene.
    pub fn new(
        intrinsics: CameraIntrinsics,
        config: RenderedAlacsConfig,
        scene: AlacsScene,
    ) -> Result<Self, AlacsError> {
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
        scene.validate()?;
        Ok(Self {
            renderer: AlacsRenderer::new(intrinsics)?,
            config,
            scene,
            slide_position_m: 0.0,
            laser_on: false,
            frames_captured: 0,
        })
    }

    /// Replaces the scene (the next capture shows it).
    pub fn set_scene(&mut self, scene: AlacsScene) -> Result<(), AlacsError> {
        scene.validate()?;
        self.scene = scene;
        Ok(())
    }

    pub fn scene(&self) -> &AlacsScene {
        &self.scene
    }

    pub fn config(&self) -> &RenderedAlacsConfig {
        &self.config
    }

    /// Bytes of one captured image.
    pub fn image_len(&self) -> usize {
        self.renderer.image_len()
    }
}

impl AlacsUnit for RenderedAlacs {
    type Error = AlacsError;

    fn intrinsics(&self) -> CameraIntrinsics {
        *self.renderer.intrinsics()
    }

    fn move_slide(&mut self, slide_position_m: f64) -> Result<f64, AlacsError> {
        check_slide_position(slide_position_m)?;
        let resolution_m = self.config.slide_resolution_m;
        let settled_m = (slide_position_m / resolution_m).round() * resolution_m;
        self.slide_position_m = settled_m.clamp(0.0, harvest_hw::alacs::SLIDE_STROKE_M);
        tracing::trace!(
            requested_m = slide_position_m,
            settled_m = self.slide_position_m,
            "ALACS slide settled"
        );
        Ok(self.slide_position_m)
    }

    fn set_laser(&mut self, on: bool) -> Result<(), AlacsError> {
        self.laser_on = on;
        Ok(())
    }

    fn capture_rgb(&mut self, rgb: &mut [u8]) -> Result<AlacsFrameInfo, AlacsError> {
        let params = LaserRenderParams {
            laser_on: self.laser_on,
            noise_seed: self
                .config
                .render
                .noise_seed
                .wrapping_add(self.frames_captured),
            ..self.config.render
        };
        self.renderer.render(
            &self.config.extrinsics,
            self.slide_position_m,
            &self.scene,
            &params,
            rgb,
        )?;
        let info = AlacsFrameInfo {
            stamp_ns: self.frames_captured * self.config.frame_period_ns,
            intrinsics: *self.renderer.intrinsics(),
            slide_position_m: self.slide_position_m,
            laser_on: self.laser_on,
        };
        self.frames_captured += 1;
        Ok(info)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use harvest_hw::alacs::conformance;

    #[test]
    fn rendered_unit_conforms() {
        let intrinsics = CameraIntrinsics::from_horizontal_fov(160, 120, 45.0);
        let mut unit = RenderedAlacs::new(
            intrinsics,
            RenderedAlacsConfig::default(),
            AlacsScene::default(),
        )
        .expect("unit");
        conformance::check_all(&mut unit).expect("conformance");
    }
}
