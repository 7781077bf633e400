//! The `strahl` command line.

mod cli;

use clap::Parser;

fn main() {
    let args = cli::Cli::parse();
    if let Err(e) = cli::run(args) {
        // Bad arguments found after parsing exit as clap's own do: usage, status 2.
        if let Some(usage) = e.downcast_ref::<clap::Error>() {
            usage.exit();
        }
        eprintln!("error: {}", strahl::errors::chain(&e));
        std::process::exit(1);
    }
}
