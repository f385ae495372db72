//! What is done with a pixel once a surface wins its depth test: the [`Shader`] trait, and the
//! depth-only, apple-owner and semantic-label shaders.

use super::V3;
use super::backdrop::BackdropHit;
use super::label;
use super::scene::{CylinderPrim, DiscPrim, SpherePrim};

/// What is done with a pixel once a surface wins its depth test.
pub(super) trait Shader {
    fn sphere(&mut self, pixel: usize, prim: &SpherePrim, hit: V3);
    fn disc(&mut self, pixel: usize, prim: &DiscPrim, across: f32);
    fn cylinder(&mut self, pixel: usize, prim: &CylinderPrim, hit: V3, along: f32);
    fn backdrop(&mut self, pixel: usize, hit: BackdropHit);
}

/// Depth only: nothing but the z-buffer.
pub(super) struct DepthOnly;

/// Depth plus, per pixel, the label of the apple that owns it (0 for anything else), so the
/// over-exposure pass can corrupt only the over-exposed apple's own pixels.
pub(super) struct DepthOwners<'a> {
    pub(super) owner: &'a mut [u32],
}

impl Shader for DepthOwners<'_> {
    #[inline(always)]
    fn sphere(&mut self, pixel: usize, prim: &SpherePrim, _: V3) {
        self.owner[pixel] = prim.label;
    }
    #[inline(always)]
    fn disc(&mut self, pixel: usize, _: &DiscPrim, _: f32) {
        self.owner[pixel] = 0;
    }
    #[inline(always)]
    fn cylinder(&mut self, pixel: usize, _: &CylinderPrim, _: V3, _: f32) {
        self.owner[pixel] = 0;
    }
    #[inline(always)]
    fn backdrop(&mut self, pixel: usize, _: BackdropHit) {
        self.owner[pixel] = 0;
    }
}

impl Shader for DepthOnly {
    #[inline(always)]
    fn sphere(&mut self, _: usize, _: &SpherePrim, _: V3) {}
    #[inline(always)]
    fn disc(&mut self, _: usize, _: &DiscPrim, _: f32) {}
    #[inline(always)]
    fn cylinder(&mut self, _: usize, _: &CylinderPrim, _: V3, _: f32) {}
    #[inline(always)]
    fn backdrop(&mut self, _: usize, _: BackdropHit) {}
}

/// Semantic labels (see [`label`]).
pub(super) struct Labels<'a> {
    pub(super) out: &'a mut [u32],
}

impl Shader for Labels<'_> {
    #[inline(always)]
    fn sphere(&mut self, pixel: usize, prim: &SpherePrim, _: V3) {
        self.out[pixel] = prim.label;
    }
    #[inline(always)]
    fn disc(&mut self, pixel: usize, _: &DiscPrim, _: f32) {
        self.out[pixel] = label::LEAF;
    }
    #[inline(always)]
    fn cylinder(&mut self, pixel: usize, _: &CylinderPrim, _: V3, _: f32) {
        self.out[pixel] = label::WOOD;
    }
    #[inline(always)]
    fn backdrop(&mut self, pixel: usize, hit: BackdropHit) {
        self.out[pixel] = match hit {
            BackdropHit::Sky => label::SKY,
            BackdropHit::NextRow { .. } => label::NEXT_ROW,
            BackdropHit::Ground { .. } => label::GROUND,
        };
    }
}
