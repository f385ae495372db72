//! The palette of the mapped views: one colour per state, used by the image overlays, the apple
//! spheres and the robot model.

use foxglove::messages::Color;

/// Red, green, blue, alpha in 0..1.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rgba(pub f64, pub f64, pub f64, pub f64);

impl From<Rgba> for Color {
    fn from(Rgba(r, g, b, a): Rgba) -> Self {
        Color { r, g, b, a }
    }
}

impl Rgba {
    /// The same colour with another alpha.
    pub fn with_alpha(self, a: f64) -> Self {
        Self(self.0, self.1, self.2, a)
    }
}

pub const WHITE: Rgba = Rgba(1.0, 1.0, 1.0, 1.0);
pub const GREY: Rgba = Rgba(0.6, 0.6, 0.6, 1.0);
pub const DARK_GREY: Rgba = Rgba(0.3, 0.3, 0.32, 1.0);
pub const PLATFORM: Rgba = Rgba(0.25, 0.22, 0.18, 1.0);
pub const YELLOW: Rgba = Rgba(1.0, 0.85, 0.1, 1.0);
pub const CYAN: Rgba = Rgba(0.1, 0.85, 1.0, 1.0);
pub const MAGENTA: Rgba = Rgba(1.0, 0.2, 0.9, 1.0);
pub const BLUE: Rgba = Rgba(0.2, 0.45, 1.0, 1.0);
pub const ORANGE: Rgba = Rgba(1.0, 0.55, 0.0, 1.0);
pub const PURPLE: Rgba = Rgba(0.6, 0.3, 0.9, 1.0);
pub const GREEN: Rgba = Rgba(0.15, 0.8, 0.25, 1.0);
pub const RED: Rgba = Rgba(0.9, 0.1, 0.1, 1.0);
