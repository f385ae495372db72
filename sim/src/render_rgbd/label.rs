//! Per-pixel labels written by
//! [`RgbdRenderer::render_labels`](super::RgbdRenderer::render_labels).

/// Sky: no surface within range.
pub const SKY: u32 = 0;
/// The next tree row behind the canopy.
pub const NEXT_ROW: u32 = 1;
pub const GROUND: u32 = 2;
pub const LEAF: u32 = 3;
/// Trunks, branches, uprights, cordons.
pub const WOOD: u32 = 4;
/// Apple `id` is labelled `APPLE_BASE + id`.
pub const APPLE_BASE: u32 = 16;
