//! Where a query or a render runs: `device="auto" | "gpu" | "cpu"`, decided as the command
//! line decides `--backend` ([`strahl_gpu::select`]), with one GPU context per process shared
//! by every scene, so that pipelines compile once.

use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use std::sync::{Arc, Mutex};
use strahl_gpu::select::{Backend, Choice, Workload, decide, on_software_device};
use strahl_gpu::{GpuContext, GpuError, instance};

/// The process's GPU context, opened by the first query or render that runs on the GPU.
static CONTEXT: Mutex<Option<Arc<GpuContext>>> = Mutex::new(None);

pub fn parse_choice(device: &str, argument: &str) -> PyResult<Choice> {
    Choice::parse(device)
        .ok_or_else(|| PyValueError::new_err(format!("{argument}={device:?}: use \"auto\", \"gpu\" or \"cpu\"")))
}

/// `auto`'s reason in Python's words (strahl-gpu words it for the command line).
fn python_words(why: String) -> String {
    why.replace("--backend gpu", "device=\"gpu\"")
}

/// The GPU error as Python sees it.
pub fn gpu_error(e: GpuError) -> PyErr {
    PyRuntimeError::new_err(e.to_string())
}

fn shared(open: impl FnOnce() -> Result<GpuContext, GpuError>) -> Result<Arc<GpuContext>, GpuError> {
    let mut slot = CONTEXT.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(ctx) = slot.as_ref() {
        return Ok(ctx.clone());
    }
    let ctx = Arc::new(open()?);
    *slot = Some(ctx.clone());
    Ok(ctx)
}

/// Where `choice` runs `workload`: `Some(context)` on the GPU, `None` on the CPU, with the
/// reason where `auto` chose. A forced GPU without a usable adapter is an error; `auto` takes
/// the CPU then, as it does where the only adapter is a software one slower than the CPU
/// backend for this work.
pub fn open(choice: Choice, workload: Workload) -> Result<(Option<Arc<GpuContext>>, Option<String>), GpuError> {
    match choice {
        Choice::Cpu => Ok((None, None)),
        Choice::Gpu => Ok((Some(shared(GpuContext::new)?), None)),
        Choice::Auto => {
            if let Some(ctx) = CONTEXT.lock().unwrap_or_else(|e| e.into_inner()).as_ref() {
                // Already open: the same decision for this work, without probing again.
                let info = ctx.adapter_info.clone();
                let (backend, why) = decide(Some(&info), workload, on_software_device);
                let why = python_words(why);
                return Ok(match backend {
                    Backend::Gpu => (Some(ctx.clone()), Some(format!("gpu ({why})"))),
                    Backend::Cpu => (None, Some(format!("cpu ({why})"))),
                });
            }
            let adapter = match instance::request_adapter() {
                Err(e @ GpuError::Environment { .. }) => return Err(e),
                r => r.ok(),
            };
            let info = adapter.as_ref().map(|a| a.get_info());
            let (backend, why) = decide(info.as_ref(), workload, on_software_device);
            let why = python_words(why);
            match (backend, adapter) {
                (Backend::Gpu, Some(adapter)) => match shared(|| GpuContext::from_adapter(&adapter)) {
                    Ok(ctx) => Ok((Some(ctx), Some(format!("gpu ({why})")))),
                    Err(e) => Ok((None, Some(format!("cpu (the GPU could not be opened: {e})")))),
                },
                _ => Ok((None, Some(format!("cpu ({why})")))),
            }
        }
    }
}
