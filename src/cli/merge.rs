//! `strahl merge`: the parts of a split render into one image.

use anyhow::Result;
use clap::Args;
use std::path::PathBuf;

#[derive(Args, Debug)]
pub struct MergeArgs {
    /// EXR parts written by `strahl render --region` or `--tile`, in any order.
    #[arg(required = true, value_name = "PART.exr")]
    pub parts: Vec<PathBuf>,
    /// The whole image: .exr (linear float, bit for bit the parts' pixels) or .png (8-bit sRGB).
    #[arg(short, long, value_parser = super::image_file_name)]
    pub output: PathBuf,
}

pub fn run(a: MergeArgs) -> Result<()> {
    strahl_core::output::check_file_target(&a.output)?;
    let (image, placement) = strahl_core::parts::merge(&a.parts)?;
    if a.output.extension().is_some_and(|e| e.eq_ignore_ascii_case("exr")) {
        strahl_core::image::write_exr(&a.output, &image, &placement)?;
    } else {
        image.save(&a.output)?;
    }
    println!("merged {} parts into {}x{}; wrote {}", a.parts.len(), image.width, image.height, a.output.display());
    Ok(())
}
