//! The textures the lanes read, decoded once per render to what
//! [`strahl_core::render::texture::texel`] returns for each texel: linear RGB and alpha, four f32. A
//! bilinear lookup then reads each of its four texels with one 16-byte load, where the packed
//! texel buffer takes a word and three reads of the sRGB table (8-bit colour) or three words
//! (linear RGB, an environment map), and interpolates the four channels of a lane together.
//! The copies take four times the memory of 8-bit textures, so they stop at [`BUDGET`]; a
//! texture past it is read from the packed buffer, texel by texel, with the same values.

use rayon::prelude::*;
use strahl_core::layout::FlatScene;
use strahl_core::render::texture::texel;

/// The most texels decoded per render, over all textures: 64 MiB of copies (one 2048 × 2048
/// texture, or sixty-four of 256 × 256).
pub(super) const BUDGET: usize = 1 << 22;

/// Decoded copies of some of a scene's textures, by index in its table.
#[derive(Clone, Debug, Default)]
pub(super) struct Texels {
    copies: Vec<Option<Vec<[f32; 4]>>>,
}

impl Texels {
    /// Copies of the textures of `g` numbered in `used` (indices into its table; repeats and
    /// numbers past the table ignored), the first ones that fit `budget` texels in all.
    pub(super) fn new(g: &FlatScene, used: impl IntoIterator<Item = usize>, budget: usize) -> Self {
        let mut copies: Vec<Option<Vec<[f32; 4]>>> = vec![None; g.textures.len()];
        let mut left = budget;
        for i in used {
            let Some(t) = g.textures.get(i) else { continue };
            let (w, h) = (t.width as usize, t.height as usize);
            let n = w.saturating_mul(h);
            if copies[i].is_some() || n == 0 || n > left {
                continue;
            }
            left -= n;
            let mut rgba = vec![[0.0f32; 4]; n];
            rgba.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
                for (x, c) in row.iter_mut().enumerate() {
                    *c = texel(&g.texels, t, x as i32, y as i32);
                }
            });
            copies[i] = Some(rgba);
        }
        Self { copies }
    }

    /// The copy of texture `i`, texel (x, y) at y·width + x, if it was made.
    #[inline(always)]
    pub(super) fn get(&self, i: usize) -> Option<&[[f32; 4]]> {
        self.copies.get(i).and_then(|c| c.as_deref())
    }
}
