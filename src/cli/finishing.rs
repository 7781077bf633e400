//! What `strahl render` adds to the image: output variables (`--aov`), written as channels of
//! its EXR file, and the denoiser (`--denoise`), guided by the albedo and normal variables,
//! both on the backend that rendered.

use anyhow::Result;
use clap::Args;
use std::path::Path;
use strahl_core::image::is_exr_path;
use strahl_core::render::aov::Aov;

#[derive(Args, Debug)]
pub struct FinishArgs {
    /// Output variables to write as channels of the EXR output beside R, G, B, comma-separated:
    /// albedo, normal (of the first non-specular surface, as a denoiser wants them), depth,
    /// position, object, material (of the pixel centre's first hit).
    #[arg(long, value_name = "LIST", value_parser = parse_aovs)]
    pub aov: Option<AovList>,
    /// Denoise the image: an edge-avoiding à-trous filter guided by the albedo and normal
    /// variables, on the backend that rendered.
    #[arg(long)]
    pub denoise: bool,
}

/// The variables `--aov` names.
#[derive(Clone, Debug)]
pub struct AovList(pub Vec<Aov>);

fn parse_aovs(s: &str) -> Result<AovList, String> {
    Aov::parse_list(s).map(AovList)
}

impl FinishArgs {
    /// A usage error for flags the output or the region cannot take, before any work.
    pub fn check(&self, output: &Path, partial: bool) -> Result<()> {
        if self.aov.is_some() && !is_exr_path(output) {
            return Err(super::usage_error(format!(
                "--aov: output variables are written as channels of an EXR file; {} is not one",
                output.display()
            )));
        }
        if self.denoise && partial {
            return Err(super::usage_error(
                "--denoise: a region or band would be filtered without its neighbours' pixels, which leaves seams \
                 where the parts meet; denoise a whole image",
            ));
        }
        Ok(())
    }

    /// The variables to write.
    pub fn written(&self) -> &[Aov] {
        self.aov.as_ref().map_or(&[], |l| &l.0)
    }

    /// The variables to compute: those written and, with --denoise, the guides.
    pub fn computed(&self) -> Vec<Aov> {
        let mut v = self.written().to_vec();
        if self.denoise {
            for g in [Aov::Albedo, Aov::Normal] {
                if !v.contains(&g) {
                    v.push(g);
                }
            }
        }
        v
    }
}
