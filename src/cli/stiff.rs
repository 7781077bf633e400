//! `strahl stiff`: the numerical-stability suite as one table.

use anyhow::Result;
use clap::{Args, ValueEnum};
use strahl::stiff::cases::{Options, run_all};
use strahl_gpu::GpuContext;

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum StiffBackend {
    Cpu,
    Gpu,
    Both,
}

#[derive(Args, Debug)]
pub struct StiffArgs {
    /// Which backends to run (the textbook rows run with the CPU; `both` runs the CPU alone,
    /// with a note, where there is no Vulkan adapter).
    #[arg(long, value_enum, default_value = "both")]
    pub backend: StiffBackend,
    /// Fraction of the full ray counts (1: 1e7 rays at closed meshes, 1e6 spawned rays, ...),
    /// in (0, 10].
    #[arg(long, default_value_t = 1.0, value_parser = ray_scale)]
    pub scale: f64,
}

fn ray_scale(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if v > 0.0 && v <= 10.0 => Ok(v),
        _ => Err(format!("must be a number in (0, 10], not {s:?}")),
    }
}

pub fn run(a: StiffArgs) -> Result<()> {
    let ctx = match a.backend {
        StiffBackend::Cpu => None,
        StiffBackend::Gpu => Some(GpuContext::new()?),
        StiffBackend::Both => match GpuContext::new() {
            Ok(ctx) => Some(ctx),
            Err(e) => {
                eprintln!("gpu backend unavailable ({e}); running the cpu rows only");
                None
            }
        },
    };
    if let Some(c) = &ctx {
        eprintln!("gpu: {}", c.adapter_name());
    }
    let opt = Options { cpu: a.backend != StiffBackend::Gpu, gpu: ctx.as_ref(), scale: a.scale };
    let rows = run_all(&opt)?;
    print!("{}", strahl::stiff::table(&rows));
    Ok(())
}
