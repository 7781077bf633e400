//! Output variables besides radiance on the GPU (`shaders/aov.wgsl`; the CPU twin is
//! `strahl-cpu`'s `aov.rs`): each pass of [`strahl_core::render::aov`] rendered as the render
//! programs are, by bands and tiles ([`crate::tiles::render_program_async`]).

use super::{FeatureKey, GpuContext, GpuError, Program, SceneBuffers, block_on};
use strahl_core::image::Region;
use strahl_core::layout::FrameParams;
use strahl_core::render::aov::{self, AOV_PASS_SHIFT, Aov, AovImages};

/// The key the AOV program is composed with for a scene whose key is `key`.
pub fn aov_key(key: FeatureKey) -> FeatureKey {
    key.for_program(Program::Aov)
}

/// The AOVs `aovs` of the pixels of `region` of the image `frame` describes.
pub fn render_aovs(
    ctx: &GpuContext,
    scene: &SceneBuffers,
    frame: &FrameParams,
    region: Region,
    aovs: &[Aov],
) -> Result<AovImages, GpuError> {
    block_on("rendering the output variables", render_aovs_async(ctx, scene, frame, region, aovs))
}

/// [`render_aovs`] without blocking, as a web page renders.
pub async fn render_aovs_async(
    ctx: &GpuContext,
    scene: &SceneBuffers,
    frame: &FrameParams,
    region: Region,
    aovs: &[Aov],
) -> Result<AovImages, GpuError> {
    let pass_ids = aov::passes(aovs);
    let mut passes = Vec::with_capacity(pass_ids.len());
    for &pass in &pass_ids {
        let f = FrameParams {
            spp: aov::aov_samples(pass, frame.spp),
            sample_base: 0,
            flags: frame.flags | pass << AOV_PASS_SHIFT,
            ..*frame
        };
        let (img, _) = crate::tiles::render_program_async(
            ctx,
            scene,
            &f,
            (Program::Aov, "aov"),
            aov_key(scene.key),
            region,
            &|_, _| {},
        )
        .await?;
        passes.push(img.pixels);
    }
    Ok(AovImages::from_passes(region.width(), region.height(), aovs, &pass_ids, &passes))
}
