//! The simulated ALACS unit's optics: a pure renderer of the unit's camera image (apples,
//! leaves, the laser stripe) from a scene, used by the simulated device (`alacs_device`) and by
//! [`rendered_unit`], an in-process unit that renders a fixed scene (tests, offline evaluation).

pub mod render;
pub mod rendered_unit;
pub mod scene;

pub use render::{AlacsRenderer, LaserRenderParams, RenderStats, render_laser_line};
pub use rendered_unit::{RenderedAlacs, RenderedAlacsConfig};
pub use scene::{AlacsScene, AppleSphere, LeafDisc, SurfaceHit, SurfaceId};
