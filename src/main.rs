//! The `strahl` command line.

mod cli;

use clap::Parser;
use strahl_gpu::instance;

fn main() {
    let args = cli::Cli::parse();
    // Only the viewer presents to a display; the rest keep Mesa's device-selection layer from
    // connecting to one (strahl_gpu::instance says why).
    if !args.command.presents() && instance::should_disable_device_select(|v| std::env::var_os(v)) {
        let (name, value) = instance::DISABLE_DEVICE_SELECT;
        // SAFETY: the first statement after parsing the arguments, before any thread exists
        // (nothing has started one yet), so no other thread reads the environment meanwhile.
        unsafe { std::env::set_var(name, value) };
    }
    if let Err(e) = cli::run(args) {
        // Bad arguments found after parsing exit as clap's own do: usage, status 2.
        if let Some(usage) = e.downcast_ref::<clap::Error>() {
            usage.exit();
        }
        eprintln!("error: {}", strahl_core::errors::chain(&e));
        std::process::exit(1);
    }
}
