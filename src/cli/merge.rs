//! `strahl merge`: the parts of a split render into one image.

use anyhow::Result;
use clap::Args;
use std::path::PathBuf;

#[derive(Args, Debug)]
pub struct MergeArgs {
    /// EXR parts written by `strahl render --region` or `--tile`, in any order.
    #[arg(required = true, value_name = "PART.exr")]
    pub parts: Vec<PathBuf>,
    /// The whole image: .exr (linear float, bit for bit the parts' pixels) or .png (8-bit sRGB,
    /// through --view).
    #[arg(short, long, value_parser = super::image_file_name)]
    pub output: PathBuf,
    #[command(flatten)]
    pub display: super::output_image::DisplayArgs,
}

pub fn run(a: MergeArgs) -> Result<()> {
    strahl_core::output::check_file_target(&a.output)?;
    a.display.check(&a.output)?;
    let (image, placement) = strahl_core::parts::merge(&a.parts)?;
    if strahl_core::image::is_exr_path(&a.output) {
        strahl_core::image::write_exr(&a.output, &image, &placement)?;
    } else {
        a.display.save_png(&image, &a.output)?;
    }
    println!("merged {} parts into {}x{}; wrote {}", a.parts.len(), image.width, image.height, a.output.display());
    Ok(())
}
