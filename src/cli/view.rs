//! `strahl view`.

use anyhow::Result;
use clap::Args;
use std::path::PathBuf;
use strahl_viewer::{ViewOptions, gpu::ViewMode};

#[derive(Args, Debug)]
pub struct ViewArgs {
    /// Scene file (TOML); reloaded when it changes on disk.
    pub scene: PathBuf,
    /// Window size in points, WxH.
    #[arg(long, default_value = "1280x720", value_parser = parse_size)]
    pub size: (u32, u32),
    /// Render resolution as a fraction of the image area's pixels (0.1 to 1).
    #[arg(long, default_value_t = 0.5, value_parser = render_scale)]
    pub scale: f32,
    /// What the image shows.
    #[arg(long, value_enum, default_value = "whitted")]
    pub mode: ViewMode,
    /// Samples per pixel to accumulate before the viewer stops refining.
    #[arg(long, default_value_t = 64, value_parser = clap::value_parser!(u32).range(1..=65536))]
    pub max_samples: u32,
    /// Run this many frames and exit (with --screenshot: this many full sample passes),
    /// printing frame timings.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=100000))]
    pub frames: Option<u32>,
    /// Save the window as this PNG file after --frames frames (default 1), then exit.
    #[arg(long, value_parser = super::png_file_name)]
    pub screenshot: Option<PathBuf>,
}

fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(|| format!("expected WxH, e.g. 1280x720, not {s:?}"))?;
    let side = |v: &str| match v.trim().parse::<u32>() {
        Ok(n) if (64..=16384).contains(&n) => Ok(n),
        _ => Err(format!("{v:?} is not a window side from 64 to 16384")),
    };
    Ok((side(w)?, side(h)?))
}

fn render_scale(s: &str) -> Result<f32, String> {
    match s.trim().parse::<f32>() {
        Ok(v) if (0.1..=1.0).contains(&v) => Ok(v),
        _ => Err(format!("must be a number from 0.1 to 1, not {s:?}")),
    }
}

pub fn run(a: ViewArgs) -> Result<()> {
    if let Some(p) = &a.screenshot {
        strahl_core::output::check_file_target(p)?;
    }
    strahl_viewer::run(ViewOptions {
        scene: a.scene,
        size: [a.size.0, a.size.1],
        scale: a.scale,
        mode: a.mode,
        max_samples: a.max_samples,
        frames: a.frames,
        screenshot: a.screenshot,
    })
}
