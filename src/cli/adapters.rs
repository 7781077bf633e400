//! `strahl adapters`: every adapter of every backend wgpu finds, with what strahl needs of it.

use anyhow::Result;
use clap::Args;
use strahl_gpu::instance;

#[derive(Args, Debug)]
pub struct AdaptersArgs {}

/// The limits strahl's shaders and buffers depend on, by wgpu's names.
fn limits(l: &wgpu::Limits) -> [(&'static str, u64); 5] {
    [
        ("max_storage_buffers_per_shader_stage", l.max_storage_buffers_per_shader_stage.into()),
        ("max_storage_buffer_binding_size", l.max_storage_buffer_binding_size),
        ("max_buffer_size", l.max_buffer_size),
        ("max_compute_invocations_per_workgroup", l.max_compute_invocations_per_workgroup.into()),
        ("max_bind_groups", l.max_bind_groups.into()),
    ]
}

/// One adapter as the lines `strahl adapters` prints for it.
fn report(index: usize, adapter: &wgpu::Adapter) -> String {
    let info = adapter.get_info();
    let l = adapter.limits();
    let f = adapter.features();
    let yes_no = |feature| if f.contains(feature) { "yes" } else { "no" };
    let mut s = format!("{index}: {}\n", info.name);
    s += &format!("  backend: {}\n", info.backend);
    s += &format!("  device type: {:?}\n", info.device_type);
    let or_none = |s: &str| if s.is_empty() { "(none reported)".to_string() } else { s.to_string() };
    s += &format!("  driver: {}\n", or_none(&info.driver));
    s += &format!("  driver info: {}\n", or_none(&info.driver_info));
    for (name, value) in limits(&l) {
        s += &format!("  {name}: {value}\n");
    }
    s += &format!("  SHADER_INT64: {}\n", yes_no(wgpu::Features::SHADER_INT64));
    s += &format!("  TIMESTAMP_QUERY: {}\n", yes_no(wgpu::Features::TIMESTAMP_QUERY));
    s += &match strahl_gpu::unmet_requirement(&l) {
        None => "  strahl runs on it: yes\n".to_string(),
        Some(why) => format!("  strahl runs on it: no ({why})\n"),
    };
    s
}

pub fn run(_: AdaptersArgs) -> Result<()> {
    let all = instance::adapters()?;
    if all.is_empty() {
        anyhow::bail!("{}", strahl_gpu::NO_ADAPTER_HINT);
    }
    let mut out = String::new();
    for (i, a) in all.iter().enumerate() {
        if i > 0 {
            out.push('\n');
        }
        out += &report(i, a);
    }
    // The list first: where WGPU_ADAPTER_NAME matches nothing, it shows what there is.
    print!("{out}");
    let chosen = instance::request_adapter().map(|a| instance::describe(&a.get_info()))?;
    println!(
        "\n--backend gpu takes {chosen} (listed best first; {} and {} choose another)",
        instance::BACKEND_VAR,
        instance::ADAPTER_NAME_VAR
    );
    Ok(())
}
