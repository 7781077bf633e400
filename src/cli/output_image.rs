//! The image a command writes: `-o OUT.png|OUT.exr` with the PNG's view transform and exposure
//! (`--view`, `--exposure`), shared by `render` and `merge`. An EXR keeps linear radiance.

use anyhow::Result;
use clap::Args;
use std::path::Path;
use strahl_core::display::ViewTransform;
use strahl_core::image::{Image, is_exr_path};

#[derive(Args, Debug)]
pub struct DisplayArgs {
    /// How a PNG shows radiance: standard (each channel clipped at 1), agx (Blender's
    /// default), neutral (Khronos PBR Neutral) or aces (Hill's ACES fit) [default: standard].
    /// An EXR keeps linear radiance and takes no view transform.
    #[arg(long, value_name = "TRANSFORM")]
    pub view: Option<ViewTransform>,
    /// Exposure of a PNG in stops: the radiance is scaled by 2^EV before --view [default: 0].
    #[arg(long, value_name = "EV", allow_negative_numbers = true, value_parser = parse_exposure)]
    pub exposure: Option<f32>,
}

/// `--exposure`: a finite number of stops within ±32 (2^32 is past any radiance f32 keeps).
fn parse_exposure(s: &str) -> Result<f32, String> {
    match s.trim().parse::<f32>() {
        Ok(ev) if ev.is_finite() && ev.abs() <= 32.0 => Ok(ev),
        Ok(_) => Err(format!("{s}: the exposure must be a finite number of stops from -32 to 32")),
        Err(e) => Err(format!("{s}: not a number of stops ({e})")),
    }
}

impl DisplayArgs {
    /// A usage error where the flags are given with an EXR output, before any work.
    pub fn check(&self, output: &Path) -> Result<()> {
        if is_exr_path(output) && (self.view.is_some() || self.exposure.is_some()) {
            return Err(super::usage_error(format!(
                "--view and --exposure shape a PNG; {} is an EXR, which keeps the linear radiance as rendered",
                output.display()
            )));
        }
        Ok(())
    }

    /// Writes `image` as a PNG through the view transform and exposure.
    pub fn save_png(&self, image: &Image, output: &Path) -> Result<()> {
        let (view, exposure) = (self.view.unwrap_or_default(), self.exposure.unwrap_or(0.0));
        strahl_core::display::save_png(image, output, view, exposure)
    }
}
