//! `strahl stiff`: the numerical-stability suite as one table.

use anyhow::Result;
use clap::{Args, ValueEnum};
use strahl::backend::gpu::GpuContext;
use strahl::stiff::cases::{Options, run_all};

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum StiffBackend {
    Cpu,
    Gpu,
    Both,
}

#[derive(Args, Debug)]
pub struct StiffArgs {
    /// Which backends to run (the textbook rows run with the CPU).
    #[arg(long, value_enum, default_value = "both")]
    pub backend: StiffBackend,
    /// Fraction of the full ray counts (1: 1e7 rays at closed meshes, 1e6 spawned rays, ...).
    #[arg(long, default_value_t = 1.0)]
    pub scale: f64,
}

pub fn run(a: StiffArgs) -> Result<()> {
    if !(a.scale > 0.0 && a.scale <= 10.0) {
        anyhow::bail!("--scale must be in (0, 10], got {}", a.scale);
    }
    let ctx = match a.backend {
        StiffBackend::Cpu => None,
        _ => Some(GpuContext::new()?),
    };
    if let Some(c) = &ctx {
        eprintln!("gpu: {}", c.adapter_name());
    }
    let opt = Options { cpu: a.backend != StiffBackend::Gpu, gpu: ctx.as_ref(), scale: a.scale };
    let rows = run_all(&opt)?;
    print!("{}", strahl::stiff::table(&rows));
    Ok(())
}
